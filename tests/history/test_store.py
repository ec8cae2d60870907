"""The calibration store and `kincal history`: records kept exactly (every field, floats bit for bit), in time
order, migrated from older schemas, refused when newer; two writers at once and writers killed at random points
lose and corrupt nothing — each on SQLite and on a real PostgreSQL server; the history table, JSON and plot
against the records added."""
import dataclasses
import hashlib
import io
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import traceback
import uuid
from contextlib import redirect_stdout
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np
import pytest
import sqlalchemy as sa

import kincal
from conftest import DATA, UR5_COLS
from kincal.history import (SCHEMA_VERSION, Identity, InputFile, Record, StoreError, calibration_record,
                            event_record, fingerprint, history_figure, migrate, model_hash, open_store,
                            save_history_figure, store_url, utc_time)
from kincal.history.store import _engine, _tables

HASH = "ab" * 32


@pytest.fixture(params=["sqlite", "postgresql"])
def url(request, tmp_path):
    """A new, empty store: an SQLite file, or a new database on the tests' PostgreSQL server."""
    if request.param == "sqlite":
        return str(tmp_path / "store.db")
    import psycopg

    server = sa.make_url(request.getfixturevalue("postgres_url"))
    name = f"t_{uuid.uuid4().hex[:12]}"
    with psycopg.connect(dbname="postgres", user="postgres", host=server.query["host"], port=server.query["port"],
                         autocommit=True) as conn:
        conn.execute(f'CREATE DATABASE "{name}"')
    return server.set(database=name).render_as_string(hide_password=False)


def sample(k: int, time="2024-03-01T10:00:00Z", name="cell-3", serial="SN-1", model=HASH, n=24, kind="calibration"):
    """A record with every field filled, its numbers drawn from seed ``k`` (no round values: exactness shows)."""
    rng = np.random.default_rng(k)
    names = [f"j{i // 4 + 1}.{'adtb'[i % 4]}" for i in range(n)]
    values = dict(zip(names, rng.normal(0.0, 0.3, n).tolist()))
    sigmas = {p: float(abs(s)) for p, s in zip(names, rng.normal(0.0, 1e-5, n))} | {names[-1]: None}
    ident = names[:-1]
    a = rng.normal(size=(len(ident), len(ident)))
    return Record(Identity(name, serial, model), kind, time, "good" if k % 2 else "suspect",
                  tuple(InputFile(f"data/run{k}-{i}.csv", hashlib.sha256(f"{k}{i}".encode()).hexdigest(),
                                  int(rng.integers(1, 10**9))) for i in range(3)),
                  values, sigmas, tuple(ident), {"names": ident, "matrix": (a @ a.T * 1e-12).tolist()},
                  {"training_mean": float(rng.uniform(1e-5, 1e-4)), "heldout_mean": float(rng.uniform(1e-5, 1e-4)),
                   "training_n": 40.0}, {"text": "target 0.2 mm off", "tool_point": rng.normal(size=3).tolist()},
                  {"temperature": (293.15 + float(rng.random()), 297.0 + float(rng.random()))}, f"record {k} ü",
                  {"command": f"kincal calibrate ur5 run{k}.csv", "kinds": {p: "length" for p in names},
                   "nested": {"list": [1, 0.1 + 0.2, None, "x", True], "tiny": 5e-300}})


def rows_of(store) -> tuple[dict, dict, dict]:
    """Every record's payload, parameter rows and input rows, read from the tables themselves."""
    t = store.tables
    with store.engine.connect() as conn:
        records = {r.id: r.payload for r in conn.execute(t["records"].select())}
        params: dict = {}
        for r in conn.execute(t["parameters"].select()):
            params.setdefault(r.record_id, {})[r.name] = (r.value, r.sigma, bool(r.identifiable))
        inputs: dict = {}
        for r in conn.execute(t["inputs"].select()):
            inputs.setdefault(r.record_id, set()).add((r.path, r.sha256, r.size))
    return records, params, inputs


def assert_complete(store) -> dict:
    """Every record readable and whole: its parameter and input rows are those of its payload, and no row
    belongs to a record that is not there. The records by id."""
    records, params, inputs = rows_of(store)
    assert set(params) <= set(records) and set(inputs) <= set(records)  # no rows without their record
    out = {}
    for rid, payload in records.items():
        rec = store.get(rid)
        assert rec == Record.from_dict(payload)
        assert params.get(rid, {}) == {n: (v, rec.sigmas.get(n), n in rec.identifiable)
                                       for n, v in rec.parameters.items()}
        assert inputs.get(rid, set()) == {(i.path, i.sha256, i.size) for i in rec.inputs}
        out[rid] = rec
    return out


def test_round_trip_every_field_and_time_order(url):
    added = [sample(1, "2024-03-02T10:00:00Z"), sample(2, "2024-03-01T11:00:00+01:00"),
             sample(3, "2024-03-01T10:00:00Z"), sample(4, "2024-03-05T08:30:00Z", serial="SN-2"),
             sample(5, "2024-03-03T00:00:00Z", kind="evaluation"), event_record(Identity("cell-3", "SN-1"), "crash",
                                                                               "2024-03-02T12:00:00Z")]
    with open_store(url) as store:
        ids = [store.add(r) for r in added]
        assert store.version == SCHEMA_VERSION
        got = store.records("cell-3", "SN-1")
        # 2 and 3 at the same instant (11:00+01:00 is 10:00 UTC): by id
        assert [i for i, _ in got] == [ids[1], ids[2], ids[0], ids[5], ids[4]]
        for i, r in got:
            assert r == added[ids.index(i)] and r.to_dict() == added[ids.index(i)].to_dict()
        assert got[0][1].time == "2024-03-01T10:00:00.000000Z"
        assert got[0][1].payload["nested"]["list"][1] == 0.1 + 0.2 and got[0][1].payload["nested"]["tiny"] == 5e-300
        assert [i for i, _ in store.records("cell-3")] == [ids[1], ids[2], ids[0], ids[5], ids[4], ids[3]]
        assert [i for i, _ in store.records("cell-3", kind="evaluation")] == [ids[4]]
        assert store.records("cell-9") == []
        assert store.robots() == [(Identity("cell-3", "SN-1", HASH), 5, "2024-03-01T10:00:00.000000Z",
                                   "2024-03-03T00:00:00.000000Z"),
                                  (Identity("cell-3", "SN-2", HASH), 1, *(["2024-03-05T08:30:00.000000Z"] * 2))]
        assert set(assert_complete(store)) == set(ids)
        with pytest.raises(StoreError, match="no record 999"):
            store.get(999)
    with open_store(url) as again:  # opened again: the same records
        assert again.records("cell-3", "SN-1") == got


def test_a_changed_nominal_model_is_recorded_and_flagged(url):
    with open_store(url) as store:
        a = store.add(sample(1, "2024-01-01T00:00Z"))
        e = store.add(event_record(Identity("cell-3", "SN-1"), "new robot file", "2024-01-02T00:00Z"))
        b = store.add(sample(2, "2024-01-03T00:00Z", model="cd" * 32))
        c = store.add(sample(3, "2024-01-04T00:00Z", model="cd" * 32))
        assert store.model_changes("cell-3") == {b} and {a, e, c}.isdisjoint(store.model_changes("cell-3", "SN-1"))
        assert store.robots()[0][0].model_hash == "cd" * 32
        assert [r.identity.model_hash for _, r in store.records("cell-3")] == [HASH, "", "cd" * 32, "cd" * 32]


def test_a_version_1_store_is_migrated_and_keeps_its_records(url):
    engine, _ = _engine(url)
    assert migrate(engine, 1) == 1
    old = [sample(1, "2024-01-01T00:00Z"), sample(2, "2024-01-02T00:00Z", model="cd" * 32)]
    t = _tables(1).tables
    with engine.begin() as conn:  # written as version 1 wrote them
        robot = conn.execute(t["robots"].insert().values(name="cell-3", serial="SN-1", model_hash=HASH)
                             ).inserted_primary_key[0]
        for r in old:
            rid = conn.execute(t["records"].insert().values(robot_id=robot, kind=r.kind, time=r.time, verdict=r.verdict,
                                                            note=r.note, payload=r.to_dict())).inserted_primary_key[0]
            conn.execute(t["parameters"].insert(), [{"record_id": rid, "name": n, "value": v, "sigma": r.sigmas[n],
                                                     "identifiable": n in r.identifiable}
                                                    for n, v in r.parameters.items()])
            conn.execute(t["inputs"].insert(), [{"record_id": rid, **i.to_dict()} for i in r.inputs])
    engine.dispose()
    with open_store(url) as store:
        assert store.version == SCHEMA_VERSION == 3
        assert [r for _, r in store.records("cell-3", "SN-1")] == old
        ids = [i for i, _ in store.records("cell-3")]
        assert store.model_changes("cell-3") == {ids[1]}  # filled in from the payloads
        new = store.add(sample(3, "2024-01-03T00:00Z"))
        assert store.model_changes("cell-3") == {ids[1], new}
        assert len(assert_complete(store)) == 3
        with store.engine.connect() as conn:
            assert {i["name"] for i in sa.inspect(conn).get_indexes("records")} == {"records_robot_time"}
            assert conn.execute(sa.text("SELECT version FROM schema_version")).scalars().all() == [3]


def test_a_store_newer_than_kincal_is_refused(url):
    with open_store(url) as store, store.engine.begin() as conn:
        conn.execute(sa.text("UPDATE schema_version SET version = 99"))
    with pytest.raises(StoreError, match="schema version 99, newer than this kincal's \\(3\\): upgrade kincal"):
        open_store(url)


def _child(work) -> None:
    """Run ``work`` in a forked child and leave without running the parent's clean-up (exit 0, or 1 with the
    traceback on stderr)."""
    code = 1
    try:
        work()
        code = 0
    except BaseException:
        traceback.print_exc()
    finally:
        os._exit(code)


@pytest.mark.slow  # 200 transactions one after the other: 2-4 s
def test_two_processes_writing_at_once_lose_nothing(url):
    open_store(url).close()  # created (and migrated) once; the writers open it themselves
    go_r, go_w = os.pipe()
    pids = []
    for w in range(2):
        pid = os.fork()
        if pid == 0:
            os.close(go_w)

            def write(w=w):
                with open_store(url) as store:
                    os.read(go_r, 1)  # both start together
                    for k in range(100):
                        store.add(sample(1000 * w + k, utc_time(datetime(2024, 1, 1, tzinfo=timezone.utc)), n=8))
            _child(write)
        pids.append(pid)
    os.write(go_w, b"go")
    assert [os.waitpid(pid, 0)[1] for pid in pids] == [0, 0]
    with open_store(url) as store:
        records = assert_complete(store)
        assert sorted(r.note for r in records.values()) == sorted(f"record {1000 * w + k} ü" for w in range(2)
                                                                  for k in range(100))
        assert len(store.records("cell-3", "SN-1")) == 200


@pytest.mark.slow  # 50 writers forked and killed: about 2 s
def test_a_writer_killed_at_random_points_leaves_whole_records(url):
    open_store(url).close()
    rng = np.random.default_rng(35)
    reported: list[int] = []
    for trial in range(50):
        read, written = os.pipe()
        pid = os.fork()
        if pid == 0:
            os.close(read)

            def write(trial=trial):
                with open_store(url) as store:
                    os.write(written, b"open\n")
                    for k in range(1000):
                        rid = store.add(sample(100 * trial + k, n=40))
                        os.write(written, f"{rid}\n".encode())  # committed
            _child(write)
        os.close(written)
        fh = os.fdopen(read)
        if trial % 5 == 0:  # now and then while it opens the store
            time.sleep(float(rng.uniform(0.0, 0.03)))
        else:  # mostly while it writes (a record takes a few ms): in a transaction, or between two
            assert fh.readline() == "open\n"
            time.sleep(float(rng.uniform(0.0, 0.015)))
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        with fh:
            reported += [int(x) for x in fh.read().split() if x != "open"]
    with open_store(url) as store:
        records = assert_complete(store)
        assert set(reported) <= set(records)  # every record its writer saw committed is there, whole
        after = store.add(sample(9999))  # the store takes new records afterwards
        assert store.get(after) == sample(9999) and len(assert_complete(store)) == len(records) + 1


def test_store_urls_and_where_the_store_is(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "config"))
    monkeypatch.delenv("KINCAL_STORE", raising=False)
    assert store_url(None) is None  # off by default
    config = tmp_path / "config" / "kincal" / "config.yaml"
    config.parent.mkdir(parents=True)
    config.write_text("store: ~/robots.db\n")
    assert store_url(None) == "~/robots.db"
    monkeypatch.setenv("KINCAL_STORE", "/srv/env.db")
    assert store_url(None) == "/srv/env.db" and store_url("given.db") == "given.db"
    monkeypatch.delenv("KINCAL_STORE")
    config.write_text("store: [1, 2]\n")
    with pytest.raises(ValueError, match="'store:' must be a path"):
        store_url(None)
    with pytest.raises(StoreError, match="the folder .*missing does not exist"):
        open_store(str(tmp_path / "missing" / "s.db"))
    with pytest.raises(StoreError, match="is a folder"):
        open_store(str(tmp_path))
    with pytest.raises(StoreError, match="give a file path or sqlite:///PATH"):
        open_store("mysql://u@h/db")
    (tmp_path / "text.db").write_text("not a database, " * 100)
    with pytest.raises(StoreError, match="text.db cannot be opened: file is not a database"):
        open_store(str(tmp_path / "text.db"))
    import importlib.util
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "psycopg" else real(name, *a))
    with pytest.raises(StoreError, match=r"pip install 'kincal\[postgres\]'"):
        open_store("postgresql://u:secret@host/db")
    with open_store(f"sqlite:///{tmp_path / 'url.db'}") as store:  # the URL form of a path
        store.add(sample(1))
    assert (tmp_path / "url.db").is_file()


def test_record_of_a_calibration(tmp_path):
    nominal = kincal.load_robot("ur5")
    meas = kincal.simulate(kincal.perturb(nominal, seed=1), nominal.sample_joints(40, seed=2), 15e-6, seed=3)
    res = kincal.calibrate(nominal, meas)
    data = tmp_path / "grid.csv"
    data.write_bytes(os.urandom(3 << 20))  # three 1 MiB blocks and more
    inputs = [fingerprint(data)]
    assert inputs[0] == InputFile(str(data), hashlib.sha256(data.read_bytes()).hexdigest(), 3 << 20)
    held = kincal.evaluate(res.robot, meas)
    rec = calibration_record(res, Identity("cell-3", "SN-1", model_hash(nominal)), inputs, heldout=[held], note="n",
                             command="kincal calibrate", covariates={"temperature": (293.0, 296.5)})
    assert rec.parameters == dict(zip(res.robot.params.names, res.robot.params.values.tolist()))
    assert rec.sigmas == {n: float(res.std[n]) for n in res.names} and rec.verdict == res.verdict.status
    assert rec.identifiable == tuple(n for n in res.robot.params.names if n in res.names and np.isfinite(res.std[n]))
    at = [res.free.index(n) for n in rec.identifiable]
    np.testing.assert_array_equal(rec.covariance["matrix"], res.covariance[np.ix_(at, at)])
    err = np.linalg.norm(res.residuals, axis=1)
    assert rec.figures["training_mean"] == pytest.approx(err.mean(), rel=1e-12)
    assert rec.figures["training_rms"] == pytest.approx(np.sqrt(np.mean(err**2)), rel=1e-12)
    assert rec.figures["heldout_mean"] == held.mean and rec.figures["heldout_n"] == 40
    assert rec.payload["calibration"]["nominal"] == nominal.params.as_dict() and rec.covariates["temperature"] == (
        293.0, 296.5)
    assert Record.from_dict(json.loads(json.dumps(rec.to_dict(), allow_nan=False))) == rec


def test_model_hash_is_the_robots_own_geometry():
    ur5 = kincal.load_robot("ur5")
    h = model_hash(ur5)
    assert len(h) == 64 and h == model_hash(kincal.load_robot("ur5"))
    assert model_hash(ur5.with_params({"base.x": 1.2, "tool.z": 0.09})) == h  # set-up, not the robot
    assert model_hash(ur5.with_params({"j2.a": ur5.params["j2.a"] + 1e-9})) != h
    assert model_hash(ur5.with_params({"j2.a": ur5.params["j2.a"] + 1e-14})) == h  # below 1e-12 m
    assert model_hash(kincal.load_robot("ur10")) != h


def test_times_are_utc_iso_text_that_sorts():
    assert utc_time("2024-05-03T14:00:00+02:00") == "2024-05-03T12:00:00.000000Z"
    assert utc_time(datetime(2024, 5, 3, 12, 0, 0, 5, tzinfo=timezone.utc)) == "2024-05-03T12:00:00.000005Z"
    with pytest.raises(ValueError, match="'yesterday' is not an ISO 8601 time"):
        utc_time("yesterday")
    with pytest.raises(ValueError, match="kind 'party' is not one of"):
        Record(Identity("r"), "party", "2024-01-01T00:00Z")
    with pytest.raises(ValueError, match="the value of 'j1.a' must be a finite number"):
        Record(Identity("r"), "calibration", "2024-01-01T00:00Z", parameters={"j1.a": float("nan")})


KINDS = {"j2.a": "length", "j3.d": "length", "j1.theta": "angle", "base.x": "length"}
NOMINAL = {"j2.a": -0.425, "j3.d": 0.1, "j1.theta": 0.0, "base.x": 1.0}
SIG = {"j2.a": 1e-5, "j3.d": 2e-5, "j1.theta": 1e-5}


def _cal(time, changes, figures):
    return Record(Identity("cell-3", "", HASH), "calibration", time, "good", (), {**NOMINAL, **changes}, SIG,
                  tuple(SIG), None, figures, None, {}, "", {"kinds": KINDS, "frame": ["base.x"]})


def history(path) -> list[Record]:
    """Three calibrations (j2.a +50 µm and j1.theta +30 µrad, then j3.d +1 µm; the frame moving each time), an
    event between the last two, an evaluation; added out of time order."""
    added = [_cal("2024-01-01T00:00Z", {}, {"training_mean": 2e-5, "heldout_mean": 3e-5}),
             _cal("2024-03-01T00:00Z", {"j2.a": -0.425 + 50e-6, "j3.d": 0.1 + 1e-6, "j1.theta": 3e-5, "base.x": 1.2},
                  {"training_mean": 2e-5, "heldout_mean": 4e-5}),
             _cal("2024-02-01T00:00Z", {"j2.a": -0.425 + 50e-6, "j1.theta": 3e-5, "base.x": 1.5},
                  {"training_mean": 2.5e-5}),
             event_record(Identity("cell-3"), "gearbox 3 replaced", "2024-02-15T00:00Z"),
             Record(Identity("cell-3", "", HASH), "evaluation", "2024-03-02T00:00Z", figures={"heldout_mean": 5e-5})]
    with open_store(str(path)) as store:
        for r in added:
            store.add(r)
    return [added[k] for k in (0, 2, 3, 1, 4)]


@pytest.fixture
def kincal_main(monkeypatch):
    """kincal's main with the history command (registered here until the command line lists it)."""
    import kincal.cli as cli
    from kincal.cli import history as history_cli, study

    subs = next(a for a in cli.build_parser()._actions if a.dest == "command")
    if "history" not in subs.choices:
        original = study.register
        monkeypatch.setattr(study, "register", lambda cmd: (original(cmd), history_cli.register(cmd)))
    return cli.main


def test_history_table_and_json_against_the_records(tmp_path, kincal_main, capsys):
    records = history(tmp_path / "s.db")
    assert kincal_main(["history", "cell-3", "--store", str(tmp_path / "s.db"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert [Record.from_dict({k: v for k, v in r.items() if k not in ("id", "model_changed")})
            for r in out["records"]] == records
    moves = {(m["before"], m["after"], m["parameter"]): m for m in out["moves"]}
    ids = [r["id"] for r in out["records"]]
    first, second, third = ids[0], ids[1], ids[3]
    assert set(moves) == {(first, second, "j2.a"), (first, second, "j1.theta"), (first, second, "base.x"),
                          (second, third, "j3.d"), (second, third, "base.x")}
    for (a, b, name), delta, sigma in (((first, second, "j2.a"), 50e-6, np.hypot(1e-5, 1e-5)),
                                       ((first, second, "j1.theta"), 3e-5, np.hypot(1e-5, 1e-5)),
                                       ((second, third, "j3.d"), 1e-6, np.hypot(2e-5, 2e-5))):
        m = moves[(a, b, name)]
        assert m["change"] == pytest.approx(delta, rel=1e-9) and m["sigma"] == pytest.approx(sigma, rel=1e-12)
        assert m["z"] == pytest.approx(delta / sigma, rel=1e-9) and not m["frame"]
    assert moves[(first, second, "base.x")]["frame"] and moves[(first, second, "base.x")]["change"] == 0.5
    assert [(s["before"], s["after"], s["test"], s["largest"]) for s in out["steps"]] == [
        (first, second, None, ["j2.a", "j1.theta"]), (second, third, None, ["j3.d"])]  # no model kept: not judged
    assert all("keeps no calibrated model" in s["not_judged"] for s in out["steps"])
    assert kincal_main(["history", "cell-3", "--store", str(tmp_path / "s.db")]) == 0
    text = capsys.readouterr().out
    assert "j2.a" in text and "+0.0500 mm" in text and "z +3.5" in text  # 50 µm / (√2 · 10 µm)
    assert "+0.00172 deg  σ 0.00081 deg  z +2.1" in text  # 30 µrad against √2 · 10 µrad
    assert "+0.0010 mm  σ 0.0283 mm  z +0.0" in text and "moved" not in text  # j3.d: 1 µm against √2 · 20 µm
    for mm in ("0.0300", "0.0400", "0.0250", "0.0500"):
        assert mm in text
    assert "gearbox" in text and "replaced" in text and "base.*" in text  # the note (wrapped at 80 columns)


def test_history_does_not_compare_values_held_in_one_calibration_only(tmp_path, kincal_main, capsys):
    """Two calibrations that held different parameters (a hexapod's design frames fixed by other coordinates: the
    Jugglebot's two sessions listed leg3.bx +9.67 mm, z +7.8, and four more legs' bx as moves): their values are
    not compared parameter by parameter, and the step says which were held where; a step between calibrations
    that held the same ones is compared as before."""
    a = _cal("2024-01-01T00:00Z", {}, {})
    b = dataclasses.replace(_cal("2024-02-01T00:00Z", {"j2.a": -0.425 + 9e-3}, {}),
                            identifiable=tuple(n for n in SIG if n != "j3.d"))
    c = dataclasses.replace(_cal("2024-03-01T00:00Z", {"j2.a": -0.425 + 9.1e-3, "j1.theta": 1e-3}, {}),
                            identifiable=tuple(n for n in SIG if n != "j3.d"))
    with open_store(str(tmp_path / "s.db")) as store:
        ids = [store.add(r) for r in (a, b, c)]
    assert kincal_main(["history", "cell-3", "--store", str(tmp_path / "s.db"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["not_compared"] == [{"before": ids[0], "after": ids[1], "held_before": [], "held_after": ["j3.d"]}]
    assert {(m["before"], m["parameter"]) for m in out["moves"]} == {(ids[1], "j2.a"), (ids[1], "j1.theta")}
    assert kincal_main(["history", "cell-3", "--store", str(tmp_path / "s.db")]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert f"#{ids[0]}" in text and "not compared parameter by parameter" in text and "held in #" in text


@pytest.mark.slow  # matplotlib's first import and drawing: 2-4 s
def test_history_plot_shows_the_records(tmp_path, kincal_main):
    import matplotlib.dates as mdates

    records = history(tmp_path / "s.db")
    with open_store(str(tmp_path / "s.db")) as store:
        rows = store.records("cell-3")
    drawn = {ax.get_title(loc="left") for ax in history_figure(rows).axes}
    assert drawn == {"j2.a", "j1.theta", "j3.d", "position error"}  # the steps' largest differences, as the text
    # lists them; the frame (base.x) left out
    fig = history_figure(rows, ["j2.a", "j3.d", "j1.theta"])
    panels = {ax.get_title(loc="left"): ax for ax in fig.axes}
    assert set(panels) == {"j2.a", "j3.d", "j1.theta", "position error"}
    cals = [r for r in records if r.kind == "calibration"]
    days = mdates.date2num([datetime.fromisoformat(r.time.replace("Z", "+00:00")) for r in cals])
    for name, factor, unit in (("j2.a", 1e3, "mm"), ("j3.d", 1e3, "mm"), ("j1.theta", 180 / np.pi, "deg")):
        # the units the text lists the differences in: j1.theta's 30 µrad as +0.00172 deg (the plot said 0.03 mrad)
        assert panels[name].get_ylabel() == f"Δ ({unit})"
        line = next(li for li in panels[name].lines if li.get_label() == name)
        want = [(r.parameters[name] - cals[0].parameters[name]) * factor for r in cals]
        np.testing.assert_allclose(mdates.date2num(line.get_xdata()), days)
        np.testing.assert_allclose(line.get_ydata(), want, atol=1e-12)
        band = panels[name].collections[0].get_paths()[0].vertices
        for x, y in zip(days, want):
            at = band[np.isclose(band[:, 0], x), 1]
            np.testing.assert_allclose([at.min(), at.max()], [y - SIG[name] * factor, y + SIG[name] * factor])
    series = {li.get_label(): li for li in panels["position error"].lines}
    np.testing.assert_allclose(series["calibration, held-out data"].get_ydata(), [0.03, 0.04])
    # one quantity per series: every calibration's training mean (Jan, Feb, Mar) beside the held-out means; the
    # training series held only Feb's (no held-out data) and a held-out mean stood in for the others
    np.testing.assert_allclose(series["calibration, training data"].get_ydata(), [0.02, 0.025, 0.02])
    np.testing.assert_allclose(series["evaluation"].get_ydata(), [0.05])
    event = mdates.date2num(datetime(2024, 2, 15, tzinfo=timezone.utc))
    for ax in fig.axes:
        assert any(np.allclose(mdates.date2num(li.get_xdata()), event) for li in ax.lines)
    assert [t.get_text() for t in panels["position error"].texts] == ["gearbox 3 replaced"]
    assert (line.get_ydata()[1] - line.get_ydata()[0]) == pytest.approx(0.00172, abs=5e-6)  # j1.theta, as the text
    fig.draw_without_rendering()  # every panel its dates: the parameter panels had none
    for name, ax in panels.items():
        dates = [t.get_text() for t in ax.get_xticklabels() if t.get_visible()]
        assert len([d for d in dates if d]) >= 2 and ax.xaxis.get_tick_params()["labelbottom"], name
    save_history_figure(fig, tmp_path / "h.svg")
    assert (tmp_path / "h.svg").read_text().count("<svg") == 1
    assert kincal_main(["history", "cell-3", "--store", str(tmp_path / "s.db"), "--plot", str(tmp_path / "h.png"),
                        "--parameters", "j2.a,base.x"]) == 0
    assert (tmp_path / "h.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_history_bad_inputs_and_events(tmp_path, kincal_main, capsys, monkeypatch):
    monkeypatch.delenv("KINCAL_STORE", raising=False)
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "nothing"))
    assert kincal_main(["history", "cell-3"]) == 1
    said = capsys.readouterr().err
    assert "no calibration store is set" in said and "--store" in said and "KINCAL_STORE" in said
    assert "config.yaml" in said
    history(tmp_path / "s.db")
    monkeypatch.setenv("KINCAL_STORE", str(tmp_path / "s.db"))
    for argv, message in ((["cell-9"], "no robot 'cell-9' in the store .* it holds: cell-3"),
                          (["cell-3", "--serial", "X"], "no robot 'cell-3' with serial 'X'"),
                          (["cell-3", "--at", "2024-01-01"], "--at gives the time of an --event"),
                          (["cell-3", "--event", "crash", "--at", "noon"], "'noon' is not an ISO 8601 time"),
                          (["cell-3", "--plot", str(tmp_path / "h.jpg")], "give a .png or .svg file"),
                          (["cell-3", "--plot", str(tmp_path / "no" / "h.png")], "does not exist"),
                          (["cell-3", "--parameters", "j2.a"], "--parameters chooses the panels of the plot"),
                          (["cell-3", "--event", "x", "--plot", str(tmp_path / "h.png"), "--parameters", "j9.a"],
                           "j9.a is in no calibration of this robot; its parameters: j2.a, j3.d, j1.theta, base.x")):
        assert kincal_main(["history", *argv]) == 1, argv
        assert re.search(message, " ".join(capsys.readouterr().err.split())), (argv, message)
    assert kincal_main(["history", "cell-3", "--event", "crash into the fence", "--at", "2024-02-20T10:00Z"]) == 0
    assert "event recorded" in capsys.readouterr().out
    with open_store(str(tmp_path / "s.db")) as store:
        events = [r for _, r in store.records("cell-3", kind="event")]
    assert [(r.note, r.time) for r in events] == [("gearbox 3 replaced", "2024-02-15T00:00:00.000000Z"),
                                                  ("crash into the fence", "2024-02-20T10:00:00.000000Z")]


def test_a_serial_new_to_a_known_robot_is_said(tmp_path, kincal_main, capsys):
    """--serial 2019302134 for 2019301234 silently started a second robot (history then asked which serial); the
    record says the store knew that robot under another serial only; the same serial again says nothing."""
    ur5 = kincal.load_robot("ur5")
    meas = kincal.simulate(kincal.perturb(ur5, seed=2), ur5.sample_joints(40, seed=1), 10e-6, seed=1)
    kincal.write_measurements(tmp_path / "m.csv", meas, ur5.joint_types)
    said = []
    for serial in ("2019301234", "2019302134", "2019301234"):
        assert kincal_main(["calibrate", "ur5", str(tmp_path / "m.csv"), "--store", str(tmp_path / "s.db"),
                            "--serial", serial]) == 0
        said.append(" ".join(capsys.readouterr().out.split()))
    assert "a new robot" not in said[0] and "a new robot" not in said[2]
    assert "a new robot: the store knew 'ur5' as serial(s) 2019301234 only (a typing slip in --serial?)" in said[1]


def test_a_past_session_is_recorded_at_its_time(tmp_path, kincal_main, capsys):
    """calibrate --store stamped every record with the time it ran, so two past sessions recorded today stood after
    an event of 2024: --at gives the session's time (UTC or local), refused without a store and when it is no time."""
    ur5 = kincal.load_robot("ur5")
    meas = kincal.simulate(kincal.perturb(ur5, seed=2), ur5.sample_joints(40, seed=1), 10e-6, seed=1)
    kincal.write_measurements(tmp_path / "m.csv", meas, ur5.joint_types)
    store = str(tmp_path / "s.db")
    assert kincal_main(["calibrate", "ur5", str(tmp_path / "m.csv"), "--store", store, "--at", "2024-01-10T09:00Z"]) == 0
    assert kincal_main(["evaluate", "ur5", str(tmp_path / "m.csv"), "--store", store, "--at", "2024-02-10T09:00Z"]) == 0
    with open_store(store) as s:
        times = [r.time for _, r in s.records("ur5", "")]
    assert times == [utc_time("2024-01-10T09:00Z"), utc_time("2024-02-10T09:00Z")]
    capsys.readouterr()
    assert kincal_main(["calibrate", "ur5", str(tmp_path / "m.csv"), "--at", "2024-01-10T09:00Z"]) == 1
    assert "--at dates the record in the calibration store, and none is set" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        kincal_main(["calibrate", "ur5", str(tmp_path / "m.csv"), "--store", store, "--at", "last tuesday"])


def _halves(tmp_path, kincal_main, capsys, link_change: float = 0.0) -> tuple[str, list[str]]:
    """The real UR5 grid's two halves calibrated into one store (poses 1-500 in January, 501-1000 in March) and the
    second half again in May with its measured positions moved by what lengthening j3.a by ``link_change`` (m)
    does (a real change of the robot): the store and the three calibrated files."""
    grid = np.genfromtxt(DATA / "ur5_grid.csv", delimiter=",", names=True)
    q = np.radians(np.column_stack([grid[c] for c in UR5_COLS]))
    ur5 = kincal.load_robot("ur5", tool=(0.0, 0.09e-3, 0.031))
    shift = (ur5.with_params({"j3.a": ur5.params["j3.a"] + link_change}).forward(q) - ur5.forward(q)) * 1e3
    lines = (DATA / "ur5_grid.csv").read_text().splitlines()
    moved = [lines[0]] + [",".join(f[:7] + [f"{float(v) + d:.6f}" for v, d in zip(f[7:10], shift[k])] + f[10:])
                          for k, f in enumerate(line.split(",") for line in lines[1:])]
    (tmp_path / "moved.csv").write_text("\n".join(moved) + "\n")
    store, files = str(tmp_path / "robots.db"), [str(tmp_path / f"{n}.yaml") for n in "ABP"]
    for data, exclude, at, out in ((DATA / "ur5_grid.csv", "501-1000", "2024-01-10T09:00Z", files[0]),
                                   (DATA / "ur5_grid.csv", "2-501", "2024-03-10T09:00Z", files[1]),
                                   (tmp_path / "moved.csv", "2-501", "2024-05-10T09:00Z", files[2])):
        assert kincal_main(["calibrate", "ur5", str(data), "--length-unit", "mm", "--angle-unit", "deg",
                            "--joint-cols", ",".join(UR5_COLS), "--tool", "0,0.09,31mm", "--exclude", exclude,
                            "--at", at, "--store", store, "-o", out]) == 0
    capsys.readouterr()
    return store, files


@pytest.mark.slow  # three calibrations of 500 real poses and four compares: about 2 s
def test_history_judges_each_step_by_compares_test(tmp_path, kincal_main, capsys):
    """Two calibrations of the real UR5 grid's two halves (an unchanged robot) made the history list ten parameters
    that 'moved' (j4.alpha +0.0896 deg, σ 0.0134, z +6.7: many single tests on the parameters' own σ) where
    compare said no significant change (p = 0.17). Each step is compare's test now: the halves are no change at
    compare's own p, their largest differences listed as such; the second half with j3.a 0.3 mm longer is
    changed, j3.a named, 0.3 mm within its σ, at compare's p."""
    store, (a, b, p) = _halves(tmp_path, kincal_main, capsys, link_change=0.3e-3)
    assert kincal_main(["history", "ur5", "--store", store, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    ids = [r["id"] for r in out["records"]]
    assert [(s["before"], s["after"]) for s in out["steps"]] == [(ids[0], ids[1]), (ids[1], ids[2])]
    for step, (first, second) in zip(out["steps"], ((a, b), (b, p))):
        code = kincal_main(["compare", first, second, "--json"])
        said = json.loads(capsys.readouterr().out)
        assert code == (4 if said["changed"] else 0)  # as check: a change is no pass
        assert step["test"]["p_value"] == pytest.approx(said["p_value"], rel=1e-9)
        assert (step["test"]["changed"], step["test"]["verdict"]) == (said["changed"], said["verdict"])
    unchanged, changed = (s["test"] for s in out["steps"])
    assert not unchanged["changed"] and unchanged["p_value"] > out["alpha"]
    assert changed["changed"] and changed["suspects"][0]["name"] == "j3.a"
    assert abs(changed["suspects"][0]["size"] - 0.3e-3) < 3 * changed["suspects"][0]["sigma"]
    assert out["steps"][0]["largest"][0] == "j4.alpha"  # the largest difference, as before: listed, not a move
    assert kincal_main(["history", "ur5", "--store", store]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert f"no significant change (p = {unchanged['p_value']:.3g})" in text and "moved" not in text
    assert "false-alarm probability 5% per step" in text and "changed (link: j3.a)" in text
    assert "j4.alpha +0.08964 deg σ 0.01338 deg z +6.7" in text


@pytest.mark.slow  # two calibrations of 500 real poses, a compare and a report: about 5 s
def test_report_history_says_each_steps_judgement(tmp_path, kincal_main, capsys):
    """The report's history drew the UR5 grid halves' parameters beyond their ±1σ bands and left out the judgement
    kincal history printed ('#1 -> #2: no significant change (p = 0.17)'): the report says each step's judgement
    with its p as history does, and its JSON keeps the steps."""
    store, (a, b, _) = _halves(tmp_path, kincal_main, capsys, link_change=0.0)
    assert kincal_main(["history", "ur5", "--store", store, "--json"]) == 0
    said = json.loads(capsys.readouterr().out)["steps"]
    out = tmp_path / "r.html"
    assert kincal_main(["report", b, "--store", store, "-o", str(out)]) == 0
    page, numbers = out.read_text(), json.loads(out.with_suffix(".json").read_text())
    ids = [s["before"] for s in said] + [said[-1]["after"]]
    verdict, p = said[0]["test"]["verdict"], said[0]["test"]["p_value"]
    assert verdict == "no significant change" and p > 0.05
    steps = page.split('<ul id="history-steps">')[1].split("</ul>")[0]
    assert f"#{ids[0]} (2024-01-10 09:00) → #{ids[1]} (2024-03-10 09:00): {verdict} (p = {p:.3g})" in steps
    assert "j4.alpha" in steps and "false-alarm probability 5 % per step" in page
    assert [s["test"]["p_value"] for s in numbers["history_steps"]] == pytest.approx([s["test"]["p_value"]
                                                                                      for s in said], rel=1e-12)


def test_history_says_nothing_is_comparable_across_a_model_change(tmp_path, kincal_main, capsys):
    """A DH calibration followed by one of a URDF model (the tool's the only parameters in common, unchanged) was
    'no parameter moved beyond 2σ', true only because nothing was compared: the step says nothing in them is
    comparable, and lists no parameter."""
    a = _cal("2024-01-01T00:00Z", {}, {})
    b = Record(Identity("cell-3", "", "cd" * 32), "calibration", "2024-02-01T00:00Z", "good", (),
               {"shoulder.x": 0.1, "j2.a": -0.425, "base.x": 1.0}, {"shoulder.x": 1e-5}, ("shoulder.x",), None,
               {}, None, {}, "", {"kinds": {}, "frame": ["base.x"]})
    with open_store(str(tmp_path / "s.db")) as store:
        ids = [store.add(r) for r in (a, b)]
    assert kincal_main(["history", "cell-3", "--store", str(tmp_path / "s.db"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["moves"] == [] and out["steps"][0]["test"] is None and out["steps"][0]["largest"] == []
    assert kincal_main(["history", "cell-3", "--store", str(tmp_path / "s.db")]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert (f"not judged: record #{ids[0]} and record #{ids[1]} are calibrations of different models (their "
            f"parameters differ: the nominal model changed), so nothing in them is comparable") in text
    assert "moved" not in text and "largest parameter differences" not in text


def _as_user(argv: list[str]) -> subprocess.CompletedProcess | None:
    """``kincal argv`` in a process a folder's mode binds: this user's when not root; root's without the
    capabilities that override file modes (setpriv) when root; None when root and setpriv is missing."""
    prefix = [] if os.geteuid() else ["setpriv", "--bounding-set", "-dac_override,-dac_read_search", "--"]
    if prefix and shutil.which("setpriv") is None:
        return None
    env = {**os.environ, "PYTHONPATH": str(Path(kincal.__file__).parents[1])}
    return subprocess.run([*prefix, sys.executable, "-m", "kincal.cli", *argv], capture_output=True, text=True,
                          env=env, timeout=120)


@pytest.mark.slow  # two kincal processes: about 3 s
def test_a_store_in_a_read_only_folder_is_read_and_not_written(tmp_path, kincal_main, capsys, monkeypatch):
    """`history ur5 --store /ro/r.db` said 'cannot be opened: unable to open database file' (the store's WAL mode
    wants its -shm file beside it, and the folder takes none): the store is read through SQLite's read-only URI
    (immutable: no write-ahead log beside it), and a record into it is refused naming the folder. Run for real
    where the folder's mode binds (not root, or root without CAP_DAC_OVERRIDE); in-process with the folder's
    check answering 'not writable', as it does there."""
    folder = tmp_path / "ro"
    folder.mkdir()
    store = folder / "s.db"
    records = history(store)
    folder.chmod(0o555)
    try:
        real = [_as_user(["history", "cell-3", "--store", str(store), *argv]) for argv in (["--json"], ["--event", "x"])]
        if real[0] is not None and real[1] is not None:
            assert real[0].returncode == 0, real[0].stderr
            assert len(json.loads(real[0].stdout)["records"]) == len(records)
            assert real[1].returncode == 1 and f"nothing recorded: the calibration store {store} can only be read " \
                f"(the folder {folder} is not writable)" in " ".join(real[1].stderr.split())
        access = os.access
        monkeypatch.setattr(os, "access", lambda p, mode, **k: False if mode & os.W_OK and Path(p) in (folder, store)
                            else access(p, mode, **k))
        assert kincal_main(["history", "cell-3", "--store", str(store), "--json"]) == 0
        assert len(json.loads(capsys.readouterr().out)["records"]) == len(records)
        assert kincal_main(["history", "cell-3", "--store", str(store), "--event", "crash"]) == 1
        assert f"can only be read (the folder {folder} is not writable)" in " ".join(capsys.readouterr().err.split())
        with open_store(str(store)) as opened, opened.engine.connect() as conn:
            assert opened.read_only == f"the folder {folder} is not writable"
            with pytest.raises(sa.exc.OperationalError, match="readonly database"):  # opened read-only
                conn.exec_driver_sql("DELETE FROM records")
        with pytest.raises(StoreError, match=f"the folder {folder} is not writable, so the store cannot be created"):
            open_store(str(folder / "new.db"))
        assert sorted(p.name for p in folder.iterdir()) == ["s.db"]  # nothing written beside it
    finally:
        folder.chmod(0o755)
    with open_store(str(store)) as s:
        assert [r for _, r in s.records("cell-3")] == records  # nor in it


def test_impossible_and_repeated_records_are_refused(tmp_path, kincal_main, capsys):
    """The same calibration recorded twice (same file, options and --at: the same sha256 and results) and records
    dated in the future were kept; an evaluation did not say which calibration it evaluated. Each is refused now,
    naming the record it repeats; an evaluation keeps the calibration's record id and the evaluated file's sha256,
    also when its data were taken before the calibration (held out from the same session)."""
    ur5 = kincal.load_robot("ur5")
    meas = kincal.simulate(kincal.perturb(ur5, seed=2), ur5.sample_joints(40, seed=1), 10e-6, seed=1)
    kincal.write_measurements(tmp_path / "m.csv", meas, ur5.joint_types)
    store, cal = str(tmp_path / "s.db"), tmp_path / "c.yaml"
    calibrate = ["calibrate", "ur5", str(tmp_path / "m.csv"), "--store", store, "--at", "2024-01-10T09:00Z"]
    assert kincal_main([*calibrate, "-o", str(cal)]) == 0
    capsys.readouterr()
    assert kincal_main([*calibrate, "-o", str(tmp_path / "c2.yaml")]) == 1  # the same session again
    said = " ".join(capsys.readouterr().err.split())
    assert "nothing recorded: the same calibration is record 1 of the store" in said and "recorded already" in said
    future = utc_time(datetime.now(timezone.utc) + timedelta(days=2))
    with pytest.raises(SystemExit):
        kincal_main([*calibrate[:-1], future])
    assert "days in the future" in capsys.readouterr().err
    assert kincal_main(["history", "ur5", "--store", store, "--event", "crash", "--at", future]) == 1
    assert "nothing recorded: the time" in capsys.readouterr().err
    evaluate = ["evaluate", str(cal), str(tmp_path / "m.csv"), "--store", store, "--at"]
    assert kincal_main([*evaluate, "2024-01-10T10:00Z"]) == 0
    # data taken before the calibration (poses held out from the same session, --at when they were taken): kept
    # and linked alike (it was refused, advising the --at given)
    assert kincal_main([*evaluate, "2024-01-09T09:00Z"]) == 0
    with open_store(store) as s:
        kept = s.records("ur5")
    assert [(i, r.kind) for i, r in kept] == [(3, "evaluation"), (1, "calibration"), (2, "evaluation")]
    assert kept[0][1].payload["evaluated"]["record"] == 1
    kept = kept[1:]
    assert kept[0][1].payload["output"]["sha256"] == hashlib.sha256(cal.read_bytes()).hexdigest()
    assert kept[1][1].payload["evaluated"] == {"path": str(cal), "sha256": hashlib.sha256(cal.read_bytes()).hexdigest(),
                                                "size": cal.stat().st_size, "record": 1}
    moved = dataclasses.replace(kept[1][1], inputs=(dataclasses.replace(kept[1][1].inputs[0], path="other.csv"),))
    with open_store(store) as s, pytest.raises(StoreError, match="the same evaluation is record 2"):
        s.add(moved)  # the same data under another name: the same session


def test_a_time_ahead_of_the_clock_by_more_than_five_minutes_is_refused():
    from kincal.history import not_in_future

    now = datetime(2024, 5, 3, 12, 0, tzinfo=timezone.utc)
    not_in_future(utc_time(now + timedelta(seconds=300)), now)  # another computer's clock, a little ahead
    with pytest.raises(ValueError, match=r"the time 2024-05-03 12:05 UTC is 5 min in the future \(now 2024-05-03 12:00"):
        not_in_future(utc_time(now + timedelta(seconds=301)), now)
    with pytest.raises(ValueError, match="is 2.0 h in the future"):
        not_in_future(utc_time(now + timedelta(hours=2)), now)
