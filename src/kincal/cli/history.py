"""A robot over its life: ``kincal history ROBOT`` (its records from the calibration store, each step between
calibrations judged by compare's test, the plot, events) and the --store flag the recording commands share."""
from __future__ import annotations

import argparse
import dataclasses
import os
import shlex
import sys

from kincal.history import (Identity, Record, Step, Store, changed_parameters, event_record, history_figure, how_to_set,
                            moves, not_compared, not_in_future, open_store, save_history_figure, steps, store_url,
                            utc_time)
from kincal.identify import ALPHA
from kincal.identify.change import EXPLAINED_MIN
from kincal.units import MM, display

from .common import check_paths, csv_list, emit


def add_store_flag(parser: argparse.ArgumentParser, recording: bool = True) -> None:
    """--store URL: the calibration store to record in (or read) and --serial, the robot's serial number there;
    declared once for every command that uses them; for a command that records (``recording``) also --at, when
    the data were taken."""
    if recording:
        parser.add_argument("--at", metavar="TIME", type=iso_time, help="when the data were taken, ISO 8601 (e.g. 2024-05-03T14:00, "
                                                        "local time; ...Z, UTC), for the store's record of a past "
                                                        "session (default: now)")
    parser.add_argument("--serial", help="the robot's serial number in the calibration store (robots are known by "
                                         "their name and serial)")
    parser.add_argument("--store", metavar="URL",
                        help="the calibration store: an SQLite file (created when missing, in a folder that exists) or "
                             "postgresql://USER@HOST/DATABASE; default: $KINCAL_STORE, else 'store:' in "
                             "~/.config/kincal/config.yaml, else none")


def iso_time(text: str) -> str:
    """argparse type: a time kincal's store takes (:func:`kincal.history.utc_time`), not in the future
    (:func:`kincal.history.not_in_future`), as given."""
    try:
        not_in_future(utc_time(text))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def store_record(args, nominal, build) -> str | None:
    """Record in the calibration store, when one is set (flag, KINCAL_STORE or the config file), the record
    ``build(identity, command)`` makes for the robot whose nominal model is ``nominal`` (named by its name and
    --serial); what was done, in words. --serial without a store is refused (it would be ignored)."""
    at = args.at  # a recording command's: when the data were taken (checked when parsed; a store: kincal.cli)
    url = store_of(args)
    if url is None:
        return None
    from kincal.history import model_hash  # noqa: PLC0415  (hashing loads nothing heavy, the store does)

    identity = Identity(nominal.name, args.serial or "", model_hash(nominal))
    made = build(identity, shlex.join(["kincal", *sys.argv[1:]]))
    made = dataclasses.replace(made, time=utc_time(at)) if at else made
    with open_store(url) as store:
        others = [i.serial for i, *_ in store.robots() if i.name == identity.name]
        number = store.add(made)
    new = f"; a new robot: the store knew '{identity.name}' as serial(s) " + ", ".join(
        o or "(none)" for o in others) + " only (a typing slip in --serial?)" if others and identity.serial not in \
        others else ""
    return f"recorded in the calibration store {url} as record {number} (robot '{identity.name}'" + \
        (f", serial {identity.serial})" if identity.serial else ")") + new


def store_of(args) -> str | None:
    """The store a recording command uses (None: none set); --serial without one is refused (it would be ignored)."""
    url = store_url(args.store)
    if url is None and args.serial is not None:
        raise ValueError(f"--serial names the robot in the calibration store, and none is set: {how_to_set()}")
    return url


def store_file(args) -> str | None:
    """The store's file when it is one (a path or sqlite:///PATH), for the checks before any work (its folder
    exists, it is no input and no other output); None for none or a server."""
    url = store_url(args.store)
    if url is None or ("://" in url and not url.startswith("sqlite:///")):
        return None
    return url[len("sqlite:///"):] if url.startswith("sqlite:///") else url


def history_for_report(args, nominal) -> dict | None:
    """The robot's history for its calibration report (rows of display texts, the plot, the store, each step between
    consecutive calibrations judged as ``kincal history`` prints it), when a store is set and holds records of the
    robot (named by the nominal model's name and --serial); None otherwise."""
    url = store_of(args)
    if url is None:
        return None
    with open_store(url) as store:
        rows = store.records(nominal.name, args.serial or "")
    if not rows:
        return None
    shown = [{"time": r.time[:16].replace("T", " "), "kind": r.kind, "verdict": r.verdict or "",
              "training": _mm(r, "training_mean") and f"{_mm(r, 'training_mean')} mm",
              "held_out": _mm(r, "heldout_mean") and f"{_mm(r, 'heldout_mean')} mm", "note": r.note}
             for _, r in rows]
    judged = steps(rows)
    said: list[dict] = []  # the steps as kincal history prints them: each head line with its indented lines
    for line in step_lines(judged, rows):
        if line.startswith(" ") and said:
            said[-1]["more"].append(line.strip())
        else:
            said.append({"line": line, "more": []})
    return {"rows": shown, "figure": history_figure(rows), "store": url, "steps": said,
            "judged": [j.to_dict() for j in judged], "alpha": ALPHA}


def store_for(given: str | None) -> str:
    """The store's URL (:func:`kincal.history.store_url`); a ValueError saying how to set one when none is."""
    url = store_url(given)
    if url is None:
        raise ValueError(f"no calibration store is set: {how_to_set()}")
    return url


def robot_in(store: Store, name: str, serial: str | None) -> Identity:
    """The robot ``name`` (of ``serial``) as the store knows it; a ValueError listing the known robots."""
    known = [ident for ident, *_ in store.robots()]
    found = [i for i in known if i.name == name and (serial is None or i.serial == serial)]
    if not found:
        listed = ", ".join(i.name + (f" (serial {i.serial})" if i.serial else "") for i in known)
        wanted = f"'{name}'" + (f" with serial '{serial}'" if serial is not None else "")
        raise ValueError(f"no robot {wanted} in the store {store.url}; "
                         + (f"it holds: {listed}" if known else "it is empty: calibrate with --store to record one"))
    if len(found) > 1:
        serials = ", ".join(i.serial or "none" for i in found)
        raise ValueError(f"the store holds robot '{name}' with several serials ({serials}): give --serial")
    return found[0]


def _mm(record: Record, figure: str) -> str:
    value = record.figures.get(figure)
    return "" if value is None else f"{value * MM:.4f}"


def _table(rows: list[tuple[int, Record]], changed: set[int]):
    from rich.table import Table

    table = Table(title=None, show_edge=False, pad_edge=False)
    table.add_column("#", justify="right")
    for head in ("time (UTC)", "kind"):
        table.add_column(head, no_wrap=True)
    table.add_column("verdict", overflow="fold")
    for head in ("train mm", "held-out mm"):  # mean position errors: never squeezed out of a narrow terminal
        table.add_column(head, justify="right", no_wrap=True, min_width=len(head))
    table.add_column("note", overflow="fold")
    for rid, r in rows:
        of = (r.payload.get("evaluated") or {}).get("record")
        note = "; ".join(filter(None, ["nominal model changed" if rid in changed else "",
                                       f"evaluates #{of}" if of else "", r.note]))
        table.add_row(str(rid), r.time[:16].replace("T", " "), r.kind, r.verdict or "", _mm(r, "training_mean"),
                      _mm(r, "heldout_mean"), note)
    return table


def step_lines(judged: list[Step], rows: list[tuple[int, Record]]) -> list[str]:
    """The steps between consecutive calibrations in words: per step kincal compare's verdict with its p-value
    (or why it was not judged), the change it names, and the parameters whose values differ most (Δ in mm/deg,
    σ, z)."""
    when = {rid: f"#{rid} ({r.time[:16].replace('T', ' ')})" for rid, r in rows}
    lines = []
    for step in judged:
        test = step.test
        head = f"{when[step.before]} → {when[step.after]}: "
        lines.append(head + (f"not judged: {step.reason}" if test is None else
                             f"{test.verdict} (p = {test.p_value:.3g})"))
        if test is not None and test.changed and test.suspects and not test.misfit:
            lines.append(f"  {'most likely single change' if test.explained >= EXPLAINED_MIN else 'closest single change'}"
                         f": {test.suspects[0].line()}")
        if step.differences:
            lines.append("  largest parameter differences (Δ, σ of both in quadrature, z = Δ/σ of each alone"
                         + ("; not judged)" if test is None else ")") + ":")
        lines += [f"    {m.name:<16} {display(m.delta, m.kind):>14}" + (
            f"  σ {display(m.sigma, m.kind, signed=False)}  z {m.z:+.1f}" if m.sigma and m.z is not None
            else "  (no σ)") for m in step.differences]
    if any(m.frame for m in moves(rows)):
        lines.append("the measurement frame (base.*) is left out: it moves whenever the tracker does")
    for a, b, held_a, held_b in not_compared(rows):
        held = "; ".join(f"held in #{i}: {', '.join(names[:6])}{' …' if len(names) > 6 else ''}"
                         for i, names in ((a, held_a), (b, held_b)) if names)
        lines.append(f"{when[a]} → {when[b]}: not compared parameter by parameter: each held at its nominal value "
                     f"parameters the other determined ({held}), so their values are in different terms (a design "
                     f"frame fixed by other coordinates, a confounded parameter taken up by another)")
    return lines


def cmd_history(args) -> int:
    if args.at and not args.event:
        raise ValueError("--at gives the time of an --event: add --event TEXT")
    if args.parameters and not args.plot:
        raise ValueError("--parameters chooses the panels of the plot: add --plot FILE.png")
    url, at = store_for(args.store), utc_time(args.at) if args.at else None
    path = store_file(args)
    if path is not None and not args.event and not os.path.exists(path):  # reading must not create one
        raise ValueError(f"no calibration store at {path}: the first command that records into it (calibrate, "
                         f"evaluate, check or compare with --store) creates it")
    if args.plot:
        if not args.plot.lower().endswith((".png", ".svg")):
            raise ValueError(f"--plot {args.plot}: give a .png or .svg file")
        check_paths([], [args.plot])
    with open_store(url) as store:
        robot = robot_in(store, args.robot, args.serial)
        rows = store.records(robot.name, robot.serial)
        changed_parameters(rows, args.parameters)  # checked before anything is recorded
        added = None
        if args.event:
            added = store.add(event_record(Identity(robot.name, robot.serial), args.event, at,
                                           command=" ".join(["kincal", *sys.argv[1:]])))
            rows = store.records(robot.name, robot.serial)
        changed = store.model_changes(robot.name, robot.serial)
    judged, apart = steps(rows), not_compared(rows)
    lines = [f"event recorded (#{added})"] if added is not None else []
    if args.plot:
        save_history_figure(history_figure(rows, args.parameters), args.plot)
        lines.append(f"plot written to {args.plot}")
    payload = {"robot": robot.name, "serial": robot.serial, "records": [
        {"id": rid, "model_changed": rid in changed, **r.to_dict()} for rid, r in rows],
        "steps": [j.to_dict() for j in judged], "alpha": ALPHA, "moves": [m.to_dict() for m in moves(rows)],
        "not_compared": [
            {"before": a, "after": b, "held_before": ha, "held_after": hb} for a, b, ha, hb in apart], "event": added, "plot": args.plot}
    if args.json:
        return emit(args, payload, "")
    from rich.console import Group
    from rich.text import Text

    head = f"{robot.name}" + (f" (serial {robot.serial})" if robot.serial else "") + f": {len(rows)} records"
    body = "\n".join(["", f"consecutive calibrations, each step judged by kincal compare's test (false-alarm "
                          f"probability {ALPHA:.0%} per step, the measurement frame re-fitted):",
                      *step_lines(judged, rows)] if judged else [])
    return emit(args, payload, Group(Text(head), _table(rows, changed), Text("\n".join([body, *lines]).strip("\n"))))


def register(cmd) -> None:
    """Add the history command through ``cmd(name, func, help, None)``."""
    s = cmd("history", cmd_history, "a robot's calibrations, evaluations, checks and events from the calibration "
                                    "store: a table, each step judged by compare's test, a plot; record an event",
            None)
    s.add_argument("robot", help="the robot's name, as given when it was calibrated with --store")
    add_store_flag(s, recording=False)
    s.add_argument("--plot", metavar="FILE", help="the history plot to write (.png or .svg): the parameters "
                                                  "against the first calibration with their ±σ bands, the "
                                                  "position errors, the events")
    s.add_argument("--parameters", type=csv_list, metavar="A,B",
                   help="the parameters to plot (default: those listed as a step's largest differences, the "
                        "measurement frame left out)")
    s.add_argument("--event", metavar="TEXT", help="record an event in the robot's life (a crash, a gearbox change)")
    s.add_argument("--at", metavar="TIME", help="when the --event happened, ISO 8601 (e.g. 2024-05-03T14:00, local "
                                                "time; 2024-05-03T12:00Z, UTC); default: now")
