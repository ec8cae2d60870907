"""Covariates: a temperature column as an input of the error model (models/covariates.py), its range
kept and enforced, read from CSV, chosen by `auto` only on held-out evidence, and the warm-up
acceptance (issue 35, acceptance 4)."""
import numpy as np
import pytest
from conftest import assert_jacobians

import kincal
from kincal.cli import main
from kincal.errors import MeasurementError, ModelError
from kincal.models import extend, with_covariates
from kincal.simulate import link_growth, simulate_thermal, warm_up

DRIFT = 0.3e-3  # m: the largest drift of a training pose over the session (acceptance 4)


@pytest.fixture(scope="module")
def warm():
    """A UR5 with geometric errors warming up over 120 poses (a real warm-up lasts 100–150) by the rise
    that moves its farthest training pose 0.3 mm (aluminium links); 40 held-out poses at temperatures
    inside the range, exact (no noise)."""
    nominal = kincal.load_robot("ur5")
    true = kincal.perturb(nominal, seed=1)
    q = nominal.sample_joints(120, seed=2)
    per_kelvin = np.linalg.norm(true.param_jacobian(q) @ link_growth(true, 23e-6), axis=1).max()  # m/K
    rise = DRIFT / per_kelvin
    train = simulate_thermal(true, q, warm_up(120, 20.0, rise), reference=20.0)
    qh = nominal.sample_joints(40, seed=3)
    Th = np.random.default_rng(4).uniform(20.0, 20.0 + rise, 40)
    held = simulate_thermal(true, qh, Th, reference=20.0, noise=0.0)
    return nominal, train, held, rise


def test_thermal_term_jacobians_match_central_differences():
    robot = with_covariates(kincal.load_robot("ur5"), ["temperature"])
    q = np.column_stack([robot.inner.sample_joints(6, seed=5), np.linspace(18.0, 31.0, 6)])
    ext = extend(robot, "thermal:temperature+harmonics:1", q)
    values = ext.params.values.copy()
    values[ext.params.indices(ext.term_names)] = np.random.default_rng(6).uniform(-3e-4, 3e-4, len(ext.term_names))
    ext = ext.with_params(values)
    assert [n for n in ext.term_names if n.endswith(".temperature")] == [f"j{i}.temperature" for i in range(1, 7)]
    assert_jacobians(ext, q, param_tol=1e-6, joint_tol=1e-7)


def test_growth_model_equals_the_simulated_growth():
    """The term with every link's rate α reproduces the links grown by α·ΔT (an exact per-sample
    rebuild of the robot): a chain's tool point is linear in its lengths."""
    true = kincal.perturb(kincal.load_robot("ur5"), seed=1)
    q, T = true.sample_joints(8, seed=7), np.linspace(20.0, 35.0, 8)
    meas = simulate_thermal(true, q, T, alpha=23e-6, reference=27.5, noise=0.0)
    model = extend(with_covariates(true, ["temperature"]), "thermal:temperature", meas.q)
    assert model.covariates[0].reference == pytest.approx(27.5)
    model = model.with_params({n: 23e-6 for n in model.term_names})
    assert np.abs(model.forward(meas.q) - meas.xyz).max() < 1e-6 * np.abs(meas.xyz - true.forward(q)).max()


def test_calibrated_file_keeps_the_range_and_reference(tmp_path, warm):
    nominal, train, _, rise = warm
    res = kincal.calibrate(with_covariates(nominal, ["temperature"]), train, error_model="thermal:temperature",
                           diagnose=False)
    path = tmp_path / "cal.yaml"
    kincal.save_robot(res.robot, path)
    back = kincal.load_robot(path)
    cov = back.covariates[0]
    assert (cov.name, cov.lower, cov.upper) == ("temperature", 20.0, pytest.approx(train.q[:, -1].max(), abs=1e-12))
    assert cov.reference == pytest.approx(np.median(train.q[:, -1]))
    assert back.term_names == res.robot.term_names
    q = train.q[::7]
    assert np.abs(back.forward(q) - res.robot.forward(q)).max() < 1e-9
    with pytest.raises(ModelError, match=r"'temperature' was fitted on \[20, "):
        back.forward(np.column_stack([q[:, :6], np.full(len(q), 20.0 + 2 * rise)]))


def test_warm_up_drift_removed_on_held_out_data_and_refused_outside(warm):
    """Acceptance 4: held-out RMS error against the drift-free truth — geometric fit vs geometric +
    thermal fit of the same warm-up session — falls by at least 80 %; outside the range: refused."""
    nominal, train, held, rise = warm
    robot = with_covariates(nominal, ["temperature"])
    rms = {}
    for model in ("geometric", "thermal:temperature"):
        fitted = kincal.calibrate(robot, train, error_model=model, diagnose=False).robot
        rms[model] = np.sqrt(np.mean(np.sum((fitted.forward(held.q) - held.xyz) ** 2, axis=1)))
    assert rms["geometric"] > 30e-6  # the drift a geometric model cannot follow
    assert 1.0 - rms["thermal:temperature"] / rms["geometric"] >= 0.8
    hot = held.q.copy()
    hot[:, -1] = 20.0 + 1.5 * rise
    with pytest.raises(ModelError, match="temperature"):
        fitted.forward(hot)


@pytest.mark.slow
def test_auto_keeps_the_thermal_term_only_when_it_wins_held_out(warm):
    nominal, train, _, rise = warm
    robot, train = with_covariates(nominal, ["temperature"]), train.subset(np.arange(0, len(train), 2))  # 60 poses
    chosen = kincal.calibrate(robot, train, error_model="auto", diagnose=False).error_model_choice
    assert chosen.chosen == "thermal:temperature"
    true = kincal.perturb(nominal, seed=1)
    still = simulate_thermal(true, train.q[:, :6], train.q[:, -1], alpha=0.0)  # the same temperatures, no growth
    rows = {r["error_model"]: r for r in kincal.calibrate(robot, still, error_model="auto",
                                                          diagnose=False).error_model_choice.rows}
    assert not rows["thermal:temperature"]["decision"].startswith(("chosen", "kept"))


def _csv(path, meas, temperature=True):
    cols = ["j1", "j2", "j3", "j4", "j5", "j6", *(["temperature"] if temperature else []), "x", "y", "z"]
    q = meas.q if temperature else meas.q[:, :6]
    rows = [",".join(f"{v:.12g}" for v in (*qi, *p)) for qi, p in zip(q, meas.xyz)]
    path.write_text(",".join(cols) + "\n" + "\n".join(rows) + "\n")
    return str(path)


def test_cli_refuses_a_temperature_outside_the_range_naming_it(tmp_path, warm, capsys):
    _, train, held, rise = warm
    data, cal = _csv(tmp_path / "warm.csv", train.subset(np.arange(0, len(train), 2))), str(tmp_path / "cal.yaml")
    store = str(tmp_path / "h.db")
    assert main(["calibrate", "ur5", data, "--covariate-cols", "temperature", "--error-model", "thermal:temperature",
                 "-o", cal, "--json", "--store", store]) == 0
    from kincal.history import open_store
    with open_store(store) as st:  # the store keeps the covariate's range in the training data
        (_, rec), = st.records("ur5")
    used = train.q[::2, 6]
    assert rec.covariates == {"temperature": pytest.approx((used.min(), used.max()), rel=1e-12)}
    hot = kincal.Measurements(np.column_stack([held.q[:, :6], np.full(len(held), 20.0 + 3 * rise)]), held.xyz,
                              held.joint_names)
    capsys.readouterr()
    assert main(["evaluate", cal, _csv(tmp_path / "hot.csv", hot)]) == 1
    message = capsys.readouterr().err
    assert "hot.csv" in message and "'temperature' was fitted on [20, " in message and "row(s) 2" in message
    assert main(["evaluate", cal, _csv(tmp_path / "held.csv", held), "--same-frame"]) == 0  # inside: accepted


def test_a_missing_covariate_column_is_named_with_the_columns_present(tmp_path, warm, capsys):
    _, train, _, _ = warm
    data = _csv(tmp_path / "plain.csv", train, temperature=False)
    assert main(["calibrate", "ur5", data, "--covariate-cols", "temperature"]) == 1
    message = capsys.readouterr().err
    assert "plain.csv" in message and "temperature" in message and "j1, j2, j3, j4, j5, j6, x, y, z" in message
    with pytest.raises(MeasurementError, match="no column temperature"):
        kincal.read_measurements(data, with_covariates(kincal.load_robot("ur5"), ["temperature"]))


def test_covariate_flag_is_refused_for_other_measurement_kinds(tmp_path, warm, capsys):
    _, train, _, _ = warm
    assert main(["calibrate", "ur5", _csv(tmp_path / "w.csv", train), "--covariate-cols", "temperature",
                 "--type", "pose"]) == 1
    assert "--covariate-cols does not apply to pose data" in capsys.readouterr().err


def test_compensation_refuses_a_model_with_covariate_terms(warm):
    """A covariate model's commands depend on the covariate at each target, which compensation does not take:
    refused with that reason (was an internal error)."""
    nominal, train, _, _ = warm
    model = extend(with_covariates(nominal, ["temperature"]), "thermal:temperature", train.q)
    targets = nominal.forward(nominal.sample_joints(3, seed=1))
    with pytest.raises(ModelError, match="covariate terms \\(temperature\\)"):
        kincal.compensate(model, targets)


def test_a_covariate_is_read_as_written_and_shown_as_one_whatever_the_length_unit(tmp_path, warm, capsys):
    """A file in mm with a temperature column: the positions are scaled, the temperature not (its calibrated
    range is the file's 20–25 °C, not 0.02–0.025); show counts six joints beside the covariate and prints its
    range as written (it printed 19000–31000 through the mm factor)."""
    import json
    from kincal.units import joint_factors
    assert joint_factors(("revolute", "prismatic", "covariate"), "mm", "deg") == [np.pi / 180, 1e-3, 1.0]
    _, train, _, _ = warm
    part = train.subset(np.arange(0, len(train), 2))
    mm = kincal.Measurements(part.q, part.xyz * 1e3, part.joint_names)
    data, cal = _csv(tmp_path / "mm.csv", mm), str(tmp_path / "cal.yaml")
    assert main(["calibrate", "ur5", data, "--covariate-cols", "temperature", "--error-model", "thermal:temperature",
                 "--length-unit", "mm", "-o", cal]) == 0
    robot = kincal.load_robot(cal)
    k = robot.joint_names.index("temperature")
    capsys.readouterr()
    assert main(["show", cal, "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)["joints"][k]
    assert shown["limits"] == pytest.approx([robot.lower[k], robot.upper[k]])
    assert robot.lower[k] < part.q[:, 6].min() < part.q[:, 6].max() < robot.upper[k] < 2 * part.q[:, 6].max()
    assert main(["show", cal]) == 0
    text = capsys.readouterr().out
    assert "6 joints; covariates temperature" in text
    row = next(line for line in text.splitlines() if "covariate" in line and "│" in line)
    assert [float(v) for v in row.split("│")[3:5]] == pytest.approx([robot.lower[k], robot.upper[k]], rel=1e-5)


def test_a_covariate_no_term_reads_is_not_needed_to_compensate_or_evaluate(tmp_path, warm, capsys):
    """The UR5's grid with a temperature column, calibrated geometric with --covariate-cols temperature: the model
    keeps the covariate, no term reads it. compensate and evaluate of the tracker's random poses (no temperature
    column) give what the same calibration without the covariate gives, byte for byte, and say the column is not
    used (compensate stopped at 'operands could not be broadcast together with shapes (20,6) (7,)', evaluate
    refused 'no column temperature'). A model whose thermal term reads it is still refused, before any work."""
    import json
    from conftest import DATA, UR5_COLS
    units = ["--length-unit", "mm", "--angle-unit", "deg", "--joint-cols", ",".join(UR5_COLS)]
    text = (DATA / "ur5_grid.csv").read_text().splitlines()
    temps = 20.0 + np.random.default_rng(0).normal(0.0, 0.5, len(text) - 1)
    grid = tmp_path / "grid_t.csv"
    grid.write_text("\n".join([text[0] + ",temperature"] + [f"{r},{t:.3f}" for r, t in zip(text[1:], temps)]) + "\n")
    covgeo, geo = str(tmp_path / "covgeo.yaml"), str(tmp_path / "geo.yaml")
    assert main(["calibrate", "ur5", str(grid), *units, "--covariate-cols", "temperature", "-o", covgeo]) == 0
    assert main(["calibrate", "ur5", str(DATA / "ur5_grid.csv"), *units, "-o", geo]) == 0
    assert kincal.load_robot(covgeo).covariate_names == ("temperature",)
    random = str(DATA / "ur5_random.csv")
    out = {}
    for name, cal in (("covgeo", covgeo), ("geo", geo)):
        capsys.readouterr()
        assert main(["compensate", cal, random, *units, "--xyz-cols", "x_target,y_target,z_target",
                     "-o", str(tmp_path / f"{name}.csv")]) == 0
        note = capsys.readouterr().err
        assert main(["evaluate", cal, random, *units, "--json"]) == 0
        out[name] = (json.loads(capsys.readouterr().out), note, (tmp_path / f"{name}.csv").read_text())
    assert out["covgeo"][2] == out["geo"][2] and out["covgeo"][2].count("\n") == 21  # 20 commands and the header
    assert out["covgeo"][0]["mean"] == pytest.approx(out["geo"][0]["mean"], rel=1e-12)
    assert out["covgeo"][0]["mean"] == pytest.approx(0.0922e-3, abs=0.00005e-3)
    assert "reads the covariate temperature: its column is not used" in out["covgeo"][1]
    assert "covariate" not in out["geo"][1]
    nominal, train, _, _ = warm
    thermal = kincal.calibrate(with_covariates(nominal, ["temperature"]), train, error_model="thermal:temperature",
                               diagnose=False)
    kincal.save_robot(thermal.robot, tmp_path / "thermal.yaml")
    for cols in (units, [*units[:-1], units[-1] + ",temperature"]):
        capsys.readouterr()
        assert main(["compensate", str(tmp_path / "thermal.yaml"), random, *cols, "--xyz-cols",
                     "x_target,y_target,z_target", "-o", str(tmp_path / "t.csv")]) == 1
        assert "has covariate terms (temperature): its commands depend on" in capsys.readouterr().err


def test_a_thermal_rate_says_its_unit_and_auto_says_what_its_regions_are_of(tmp_path, warm, capsys):
    """The table printed 'j1.temperature -0.0148 %' without its unit (per unit of the covariate: %/K for a
    temperature in K or °C); it says '(per unit of temperature)', the JSON's units '1, per unit of temperature'.
    A covariate column changed every row of auto's table (UR5 grid: harmonics:1 0.0933 -> 0.0950 mm) under a header
    saying the regions are of joint space: the k-means of the regions reads the covariate too (for the thermal
    candidate's sake), and the header says so."""
    import json
    import re
    from kincal.identify.select import blocked_folds
    nominal, train, _, _ = warm
    data = _csv(tmp_path / "warm.csv", train.subset(np.arange(0, len(train), 2)))
    args = ["calibrate", "ur5", data, "--covariate-cols", "temperature", "--error-model", "thermal:temperature"]
    main([*args, "--json"])
    units = json.loads(capsys.readouterr().out)["units"]
    main(args)
    text = capsys.readouterr().out
    rows = re.findall(r"^(j\d\.temperature) +[+-][\d.]+ % .*\(per unit of temperature\)$", text, re.M)
    assert rows and set(rows) == {n for n, u in units.items() if u == "1, per unit of temperature"}
    q = train.q[::2]
    plain = blocked_folds(nominal, q[:, :6], 5)
    read = blocked_folds(with_covariates(nominal, ["temperature"]), q, 5)
    assert any(not np.array_equal(a, b) for a, b in zip(plain, read))  # the covariate moves the regions
    few = train.subset(np.arange(0, len(train), 3))  # 40 poses
    choice = kincal.calibrate(with_covariates(nominal, ["temperature"]), few, error_model="auto",
                              diagnose=False).error_model_choice
    assert str(choice).startswith("error model by blocked cross-validation (5 regions of joint space and "
                                  "temperature): ")
    assert choice.to_dict()["regions"] == "joint space and temperature"
    assert str(kincal.identify.select.ErrorModelChoice((), "geometric", 5)).startswith(
        "error model by joint-space blocked cross-validation (5 regions): geometric")
