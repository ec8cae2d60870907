"""What the calibration store keeps: a robot's identity, the input files' fingerprints, and one record
per calibration, evaluation, check, comparison or event, all in SI (m, rad) and JSON-safe (no NaN:
None where a value is unknown)."""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

from ..errors import ModelError
from ..models.robot import TOOL_NAMES, Robot
from ..models.yaml_io import robot_to_yaml

KINDS = ("calibration", "evaluation", "check", "comparison", "event")
TIME_FORMAT = "%Y-%m-%dT%H:%M:%S.%fZ"  # UTC, microseconds always: the text sorts as the time does
HASH_DIGITS = 12  # nominal values rounded to 1e-12 (m, rad) in the model hash
FUTURE_TOLERANCE_S = 300.0  # a record's time may be this far ahead of the clock (another computer's clock)


def utc_time(value: str | datetime | None = None) -> str:
    """A time as the store's UTC ISO 8601 text, e.g. '2024-05-03T14:00:00.000000Z'.

    The text has microseconds always, so it sorts as the time does.

    Parameters
    ----------
    value : str or datetime, optional
        An ISO 8601 text ('Z' or an offset for UTC or another zone) or a datetime; one without a zone is
        this computer's local time. None (default): now.

    Returns
    -------
    str
        The time in UTC, ``YYYY-MM-DDTHH:MM:SS.ffffffZ``.

    Raises
    ------
    ValueError
        Naming a text that is no ISO 8601 time.

    Examples
    --------
    >>> from datetime import datetime, timezone
    >>> from kincal.history import utc_time
    >>> utc_time("2024-05-03T12:00Z")
    '2024-05-03T12:00:00.000000Z'
    >>> utc_time("2024-05-03T14:00+02:00")
    '2024-05-03T12:00:00.000000Z'
    >>> utc_time(datetime(2024, 5, 3, 12, 0, 30, tzinfo=timezone.utc))
    '2024-05-03T12:00:30.000000Z'
    >>> utc_time("May 3rd")
    Traceback (most recent call last):
        ...
    ValueError: 'May 3rd' is not an ISO 8601 time; write e.g. 2024-05-03T14:00 (local time) or ...
    """
    if value is None:
        moment = datetime.now(timezone.utc)
    elif isinstance(value, datetime):
        moment = value
    else:
        text = value.strip()
        try:
            moment = datetime.fromisoformat(text[:-1] + "+00:00" if text.endswith(("Z", "z")) else text)
        except ValueError:
            raise ValueError(f"'{value}' is not an ISO 8601 time; write e.g. 2024-05-03T14:00 (local time) or "
                             f"2024-05-03T12:00Z (UTC)") from None
    if moment.tzinfo is None:
        moment = moment.astimezone()  # local time
    return moment.astimezone(timezone.utc).strftime(TIME_FORMAT)


def parse_time(text: str) -> datetime:
    """The store's time text as an aware UTC datetime.

    Parameters
    ----------
    text : str
        A time as :func:`utc_time` writes it, ``YYYY-MM-DDTHH:MM:SS.ffffffZ``.

    Returns
    -------
    datetime
        The time, with the UTC zone.

    Raises
    ------
    ValueError
        When the text is not in the store's format.

    Examples
    --------
    >>> from kincal.history import parse_time
    >>> parse_time("2024-05-03T12:00:00.000000Z")
    datetime.datetime(2024, 5, 3, 12, 0, tzinfo=datetime.timezone.utc)
    """
    return datetime.strptime(text, TIME_FORMAT).replace(tzinfo=timezone.utc)


def not_in_future(text: str, now: datetime | None = None) -> None:
    """Refuse a record's time later than now (beyond ``FUTURE_TOLERANCE_S``, clocks that differ a little): a record
    is dated when its data were taken.

    Parameters
    ----------
    text : str
        A time as :func:`utc_time` writes it.
    now : datetime, optional
        The present (default: this computer's clock).

    Raises
    ------
    ValueError
        Naming the time, how far ahead it is and the present.

    Examples
    --------
    >>> from datetime import datetime, timezone
    >>> from kincal.history import not_in_future
    >>> now = datetime(2024, 5, 3, 12, 0, tzinfo=timezone.utc)
    >>> not_in_future("2024-05-03T12:04:00.000000Z", now)  # within the tolerance
    >>> not_in_future("2025-05-03T12:00:00.000000Z", now)
    Traceback (most recent call last):
        ...
    ValueError: the time 2025-05-03 12:00 UTC is 365.0 days in the future (now 2024-05-03 12:00 UTC): ...
    """
    now = now or datetime.now(timezone.utc)
    ahead = (parse_time(text) - now).total_seconds()
    if ahead > FUTURE_TOLERANCE_S:
        size = f"{ahead / 86400:.1f} days" if ahead >= 86400 else f"{ahead / 3600:.1f} h" if ahead >= 3600 else \
            f"{ahead / 60:.0f} min"
        raise ValueError(f"the time {text[:16].replace('T', ' ')} UTC is {size} in the future (now "
                         f"{utc_time(now)[:16].replace('T', ' ')} UTC): a record is dated when its data were taken; "
                         f"give that time (a local time without a zone, or ...Z for UTC)")


def json_safe(obj: Any) -> Any:
    """``obj`` as plain JSON values: numpy arrays and numbers as lists and Python numbers, tuples as lists,
    keys as text, a non-finite number as None (unknown)."""
    if isinstance(obj, Mapping):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, np.ndarray)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(obj) else None
    if obj is None or isinstance(obj, str):
        return obj
    raise TypeError(f"a store record holds JSON values only, not {type(obj).__name__}")


@dataclass(frozen=True)
class Identity:
    """A robot as the user names it, and its nominal model.

    Parameters
    ----------
    name : str
        The robot's name (the name given at calibration); not empty.
    serial : str, optional
        Its serial number ('' when none given; default '').
    model_hash : str, optional
        The sha256 of its nominal model (:func:`model_hash`; '' for an event, which has no model;
        default '').

    Raises
    ------
    ValueError
        When ``name`` is empty.

    Examples
    --------
    >>> from kincal.history import Identity
    >>> Identity("cell-3 arm", "SN42").to_dict()
    {'name': 'cell-3 arm', 'serial': 'SN42', 'model_hash': ''}
    >>> Identity(" ")
    Traceback (most recent call last):
        ...
    ValueError: a robot in the store needs a name (the name given at calibration)
    """

    name: str
    serial: str = ""
    model_hash: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise ValueError("a robot in the store needs a name (the name given at calibration)")

    def to_dict(self) -> dict:
        """The identity as JSON-ready values."""
        return {"name": self.name, "serial": self.serial, "model_hash": self.model_hash}

    @classmethod
    def from_dict(cls, d: Mapping) -> "Identity":
        """The identity from :meth:`to_dict`'s values (serial and model hash '' when missing)."""
        return cls(str(d["name"]), str(d.get("serial") or ""), str(d.get("model_hash") or ""))


@dataclass(frozen=True)
class InputFile:
    """An input file's fingerprint.

    Parameters
    ----------
    path : str
        The file's path as given.
    sha256 : str
        The sha256 of its bytes, 64 hexadecimal digits.
    size : int
        Its size, bytes.

    See Also
    --------
    fingerprint : takes it from a file.
    """

    path: str
    sha256: str
    size: int

    def to_dict(self) -> dict:
        """The fingerprint as JSON-ready values."""
        return {"path": self.path, "sha256": self.sha256, "size": self.size}

    @classmethod
    def from_dict(cls, d: Mapping) -> "InputFile":
        """The fingerprint from :meth:`to_dict`'s values."""
        return cls(str(d["path"]), str(d["sha256"]), int(d["size"]))


def fingerprint(path: str | Path) -> InputFile:
    """The sha256 and size of a file (read in 1 MiB blocks: any size).

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    InputFile
        Its path as given, the sha256 of its bytes (hex) and its size, bytes.

    Raises
    ------
    OSError
        When the file cannot be read.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from kincal.history import fingerprint
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     data = Path(folder) / "run1.csv"
    ...     _ = data.write_bytes(b"q1,q2,q3\\n")
    ...     found = fingerprint(data)
    >>> found.size, found.sha256[:16], found.path.endswith("run1.csv")
    (9, '4530e8e323239ec0', True)
    """
    digest, size = hashlib.sha256(), 0
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
            size += len(block)
    return InputFile(str(path), digest.hexdigest(), size)


def model_hash(robot: Robot) -> str:
    """The sha256 of the robot's own nominal model, which tells when a robot's model was changed.

    The hash is taken of a canonical JSON of its structure, joint names and types, and its parameters'
    names, kinds and values rounded to 1e-12 (m, rad). The measurement frame (base) and the measured point
    (tool) are the set-up, not the robot: left out, so a moved tracker or reflector is no new model.

    Parameters
    ----------
    robot : Robot
        The nominal robot (a calibrated file's nominal values), not the calibrated one.

    Returns
    -------
    str
        64 hexadecimal digits.

    Examples
    --------
    >>> import kincal
    >>> from kincal.history import model_hash
    >>> robot = kincal.load_robot("ur5")
    >>> h = model_hash(robot)
    >>> len(h)
    64
    >>> model_hash(robot.with_params({"tool.z": robot.params["tool.z"] + 0.01})) == h  # the set-up
    True
    >>> model_hash(robot.with_params({"j2.a": robot.params["j2.a"] + 1e-3})) == h  # the robot
    False
    """
    setup = set(robot.base_params()) | set(TOOL_NAMES)
    params = [[n, k, round(float(v), HASH_DIGITS) + 0.0]  # + 0.0: -0.0 and 0.0 hash alike
              for n, k, v in zip(robot.params.names, robot.params.kinds, robot.params.values) if n not in setup]
    text = json.dumps({"structure": robot.structure, "joints": list(robot.joint_names),
                       "joint_types": list(robot.joint_types), "parameters": params}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def _floats(d: Mapping | None, where: str, none_ok: bool = False) -> dict:
    """``d`` with text keys and float values, checked finite (None allowed with ``none_ok``); a ValueError
    names the entry otherwise."""
    out: dict[str, float | None] = {}
    for k, v in (d or {}).items():
        if v is None and none_ok:
            out[str(k)] = None
        elif isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ValueError(f"store record: {where} of '{k}' must be a finite number, not {v!r}")
        else:
            out[str(k)] = float(v)
    return out


@dataclass(frozen=True)
class Record:
    """One entry of a robot's history, SI (m, rad) and JSON-safe (None where a value is unknown).

    The numbers are checked finite when the record is built, the time is brought to UTC
    (:func:`utc_time`) and ``covariance``, ``mounting`` and ``payload`` are made plain JSON values.

    Parameters
    ----------
    identity : Identity
        The robot.
    kind : str
        One of :data:`KINDS`: "calibration", "evaluation", "check", "comparison", "event".
    time : str or datetime
        When it happened, as :func:`utc_time` reads it (kept as UTC ISO 8601 text).
    verdict : str or None, optional
        "good", "suspect", "refused" (a calibration), a check's answer, or None (default).
    inputs : tuple of InputFile, optional
        The input files' fingerprints (default none).
    parameters : dict, optional
        name -> value of every robot parameter of the model (a calibration), m or rad.
    sigmas : dict, optional
        name -> 1-σ of each fitted robot parameter, m or rad (None: undetermined).
    identifiable : tuple of str, optional
        The robot parameters the data determined (finite σ), in model order.
    covariance : dict or None, optional
        ``{"names": [...], "matrix": [[...]]}`` over ``identifiable`` (m², rad², m·rad), or None.
    figures : dict, optional
        name -> value: training_mean, training_rms, training_max, training_n, heldout_mean, … (m; the
        ``_n`` figures count samples).
    mounting : dict or None, optional
        The tool point found against the declared one (``{"tool_point", "declared_tool_point",
        "text"}``), or None.
    covariates : dict, optional
        name -> (low, high): the range of each covariate in the data (temperature in K, time in s).
    note : str, optional
        The user's words (an event's description).
    payload : dict, optional
        Any other JSON detail: the calibrated file's ``calibration`` section, the command line, kincal's
        version, the parameters' kinds.

    Attributes
    ----------
    kinds : dict
        name -> "length", "angle" or "ratio" of the parameters (from the payload; "length" when
        unknown).

    Raises
    ------
    ValueError
        When ``kind`` is not one of :data:`KINDS`, the time is not an ISO 8601 time, or a number is not
        finite.

    Examples
    --------
    >>> from kincal.history import Identity, Record
    >>> r = Record(Identity("cell-3 arm"), "calibration", "2024-05-03T14:00+02:00", "good",
    ...            parameters={"j2.theta": 1e-3, "j3.a": 0.425}, sigmas={"j2.theta": 2e-5, "j3.a": None},
    ...            payload={"kinds": {"j2.theta": "angle"}})
    >>> r.time, r.kinds
    ('2024-05-03T12:00:00.000000Z', {'j2.theta': 'angle', 'j3.a': 'length'})
    >>> Record.from_dict(r.to_dict()) == r
    True
    >>> Record(Identity("cell-3 arm"), "repair", "2024-05-03T14:00")
    Traceback (most recent call last):
        ...
    ValueError: store record: kind 'repair' is not one of calibration, evaluation, check, comparison, event
    """

    identity: Identity
    kind: str
    time: str
    verdict: str | None = None
    inputs: tuple[InputFile, ...] = ()
    parameters: dict = field(default_factory=dict)
    sigmas: dict = field(default_factory=dict)
    identifiable: tuple[str, ...] = ()
    covariance: dict | None = None
    figures: dict = field(default_factory=dict)
    mounting: dict | None = None
    covariates: dict = field(default_factory=dict)
    note: str = ""
    payload: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"store record: kind '{self.kind}' is not one of {', '.join(KINDS)}")
        object.__setattr__(self, "time", utc_time(self.time))
        object.__setattr__(self, "inputs", tuple(self.inputs))
        object.__setattr__(self, "identifiable", tuple(self.identifiable))
        object.__setattr__(self, "parameters", _floats(self.parameters, "the value"))
        object.__setattr__(self, "sigmas", _floats(self.sigmas, "the σ", none_ok=True))
        object.__setattr__(self, "figures", _floats(self.figures, "the figure"))
        ranges = {}
        for k, v in self.covariates.items():
            low, high = _floats({"low": v[0], "high": v[1]}, f"covariate {k}'s range").values()
            ranges[str(k)] = (low, high)
        object.__setattr__(self, "covariates", ranges)
        for name, value in (("covariance", self.covariance), ("mounting", self.mounting), ("payload", self.payload)):
            object.__setattr__(self, name, None if value is None else json_safe(value))

    @property
    def kinds(self) -> dict[str, str]:
        """name -> "length", "angle" or "ratio" of the parameters (from the payload; "length" when unknown)."""
        kinds = self.payload.get("kinds") or {}
        return {n: str(kinds.get(n, "length")) for n in self.parameters}

    def to_dict(self) -> dict:
        """The record as JSON-ready values (what the store keeps)."""
        return {"identity": self.identity.to_dict(), "kind": self.kind, "time": self.time, "verdict": self.verdict,
                "inputs": [i.to_dict() for i in self.inputs], "parameters": dict(self.parameters),
                "sigmas": dict(self.sigmas), "identifiable": list(self.identifiable), "covariance": self.covariance,
                "figures": dict(self.figures), "mounting": self.mounting,
                "covariates": {k: list(v) for k, v in self.covariates.items()}, "note": self.note,
                "payload": self.payload}

    @classmethod
    def from_dict(cls, d: Mapping) -> "Record":
        """The record from :meth:`to_dict`'s values (the fields that are missing take their defaults)."""
        return cls(Identity.from_dict(d["identity"]), str(d["kind"]), str(d["time"]), d.get("verdict"),
                   tuple(InputFile.from_dict(i) for i in d.get("inputs") or ()), dict(d.get("parameters") or {}),
                   dict(d.get("sigmas") or {}), tuple(d.get("identifiable") or ()), d.get("covariance"),
                   dict(d.get("figures") or {}), d.get("mounting"),
                   {k: tuple(v) for k, v in (d.get("covariates") or {}).items()}, str(d.get("note") or ""),
                   dict(d.get("payload") or {}))

    def same_as(self, other: "Record") -> bool:
        """Whether ``other`` says what this record says: the same robot, kind, time, verdict, note, input files by
        their sha256 (not their paths), parameters, σ and figures: the same session recorded twice, however it
        was asked for (the command line, the output file's name)."""
        def said(r: Record) -> tuple:
            return (r.identity.name, r.identity.serial, r.kind, r.time, r.verdict, r.note,
                    sorted(i.sha256 for i in r.inputs), r.parameters, r.sigmas, r.figures)
        return said(self) == said(other)


def _combined(stats: Iterable[Any], prefix: str) -> dict[str, float]:
    """Sets' position statistics (EvaluationStats or a set's stats dict, m) as one: mean and RMS weighted by
    the samples, the largest max, the samples; {} when none."""
    parts = [dict(s) if isinstance(s, Mapping) else s.to_dict() for s in stats]
    parts = [p for p in parts if p.get("mean") is not None]
    if not parts:
        return {}
    n = np.array([float(p.get("n", p.get("samples", 1))) for p in parts])
    mean = np.array([p["mean"] for p in parts], float)
    rms = np.array([p.get("rms", p["mean"]) for p in parts], float)
    out = {f"{prefix}_mean": float(n @ mean / n.sum()), f"{prefix}_rms": float(np.sqrt(n @ rms**2 / n.sum())),
           f"{prefix}_n": float(n.sum())}
    if all(p.get("max") is not None for p in parts):
        out[f"{prefix}_max"] = float(max(p["max"] for p in parts))
    return out


def _finite(value: Any) -> float | None:
    return float(value) if value is not None and np.isfinite(value) else None


def _about(command: str, robot: Robot | None = None) -> dict:
    """The payload every record carries: the command line, kincal's version, the parameters' kinds and which
    of them are the measurement frame (set-up, not the robot)."""
    from .. import __version__

    out: dict = {"command": command, "kincal": __version__}
    if robot is not None:
        out |= {"kinds": dict(zip(robot.params.names, robot.params.kinds)), "frame": list(robot.base_params()),
                "structure": robot.structure, "error_model": robot.error_model}
    return out


def _model_text(robot: Robot) -> str | None:
    """The calibrated robot's file text in SI units (it loads back exactly), which the history compares
    consecutive calibrations by (:func:`kincal.history.steps`); None for a kind of model kincal has no file for."""
    try:
        return robot_to_yaml(robot)
    except ModelError:
        return None


def calibration_record(result: Any, identity: Identity, inputs: Iterable[InputFile],
                       heldout: Iterable[Any] | None = None, note: str = "", command: str = "",
                       covariates: Mapping | None = None, time: str | datetime | None = None,
                       output: InputFile | None = None) -> Record:
    """The record of a calibration.

    It keeps every robot parameter's value, the fitted ones' σ, the identifiable set (finite σ) and its
    covariance, the verdict, the training figures (the kept poses of position data, else every set's
    position statistics) and the held-out ones, the mounting, the covariates and, in the payload, the
    calibrated file's ``calibration`` section, the calibrated model's file text (SI: it loads back exactly;
    the history compares calibrations by it), the command, kincal's version and the parameters' kinds.

    Parameters
    ----------
    result : CalibrationResult
        The calibration (:func:`kincal.calibrate`).
    identity : Identity
        The robot.
    inputs : iterable of InputFile
        The input files' fingerprints (:func:`fingerprint`).
    heldout : iterable, optional
        Held-out statistics: :class:`kincal.EvaluationStats` or sets' statistics dicts, m (default none).
    note : str, optional
        The user's words (default '').
    command : str, optional
        The command line (default '').
    covariates : mapping, optional
        name -> (low, high): the range of each covariate in the data (temperature in K, time in s).
    time : str or datetime, optional
        When it was calibrated (:func:`utc_time`); None (default): now.
    output : InputFile, optional
        The fingerprint of the calibrated robot file written (an evaluation of that file is linked to this
        record by its sha256); None (default): none written.

    Returns
    -------
    Record
        A record of kind "calibration".

    Examples
    --------
    >>> import kincal
    >>> from kincal.history import Identity, calibration_record, model_hash
    >>> robot = kincal.load_robot("ur5")
    >>> true = kincal.perturb(robot, seed=1)
    >>> meas = kincal.simulate(true, robot.sample_joints(40, seed=2), 15e-6, seed=3)
    >>> test = kincal.simulate(true, robot.sample_joints(20, seed=4), 15e-6, seed=5)
    >>> result = kincal.calibrate(robot, meas)
    >>> rec = calibration_record(result, Identity("cell-3 arm", "SN42", model_hash(robot)), [],
    ...                          heldout=[kincal.evaluate(result.robot, test)], time="2024-05-03T12:00Z")
    >>> rec.kind, rec.verdict, len(rec.parameters), len(rec.identifiable)
    ('calibration', 'good', 35, 27)
    >>> rec.figures["training_n"], rec.figures["heldout_n"]
    (40.0, 20.0)
    """
    robot = result.robot
    sigmas = {n: _finite(result.std.get(n)) for n in result.names}
    ident = tuple(n for n in robot.params.names if sigmas.get(n) is not None)
    at = [result.free.index(n) for n in ident]
    covariance = {"names": list(ident), "matrix": result.covariance[np.ix_(at, at)]} if ident else None
    figures = _combined([result.stats_after] if result.data else result.per_set, "training")
    figures |= _combined(heldout or (), "heldout")
    mounting = None if not result.mounting else {
        "tool_point": None if result.mounting_gauge[0] else robot.tool_point(),  # None: the data do not determine it
        "declared_tool_point": result.nominal.tool_point(), "text": result.mounting}
    payload = _about(command, robot) | {"estimated": list(result.names), "calibration": json_safe(result.record()),
                                        "model": _model_text(robot),
                                        "output": None if output is None else output.to_dict()}
    return Record(identity, "calibration", utc_time(time), result.verdict.status, tuple(inputs),
                  robot.params.as_dict(), sigmas, ident, covariance, figures, mounting, dict(covariates or {}), note,
                  payload)


def evaluation_record(stats: Any, identity: Identity, inputs: Iterable[InputFile], note: str = "",
                      command: str = "", covariates: Mapping | None = None, time: str | datetime | None = None,
                      robot: Robot | None = None, evaluated: InputFile | None = None) -> Record:
    """The record of an evaluation: a model's errors on data it was not fitted on.

    The statistics are combined into the held-out figures (heldout_mean, heldout_rms, heldout_max,
    heldout_n; m); each file's statistics are kept in the payload.

    Parameters
    ----------
    stats : EvaluationStats or dict, or a list or tuple of them
        One :class:`kincal.EvaluationStats` or statistics dict per file, m.
    identity : Identity
        The robot.
    inputs : iterable of InputFile
        The input files' fingerprints (:func:`fingerprint`).
    note : str, optional
        The user's words (default '').
    command : str, optional
        The command line (default '').
    covariates : mapping, optional
        name -> (low, high): the range of each covariate in the data (temperature in K, time in s).
    time : str or datetime, optional
        When it was evaluated (:func:`utc_time`); None (default): now.
    robot : Robot, optional
        The model evaluated (its parameters' kinds in the payload).
    evaluated : InputFile, optional
        The fingerprint of the robot file evaluated: the store links the record to the calibration that wrote
        it (:meth:`Store.add`); None (default): a model of no file (a bundled robot).

    Returns
    -------
    Record
        A record of kind "evaluation".

    Examples
    --------
    >>> from kincal.history import Identity, evaluation_record
    >>> stats = [{"mean": 40e-6, "rms": 50e-6, "max": 0.1e-3, "n": 30},
    ...          {"mean": 70e-6, "rms": 80e-6, "max": 0.2e-3, "n": 10}]
    >>> rec = evaluation_record(stats, Identity("cell-3 arm"), [], time="2024-05-03T12:00Z")
    >>> {k: round(v, 9) for k, v in rec.figures.items()}  # weighted by the samples
    {'heldout_mean': 4.75e-05, 'heldout_rms': 5.8949e-05, 'heldout_n': 40.0, 'heldout_max': 0.0002}
    """
    parts = list(stats) if isinstance(stats, (list, tuple)) else [stats]
    figures = _combined(parts, "heldout")
    details = [dict(p) if isinstance(p, Mapping) else p.to_dict() for p in parts]
    return Record(identity, "evaluation", utc_time(time), None, tuple(inputs), figures=figures,
                  covariates=dict(covariates or {}), note=note,
                  payload=_about(command, robot) | {"evaluation": json_safe(details),
                                                    "evaluated": None if evaluated is None else evaluated.to_dict()})


def event_record(identity: Identity, note: str, time: str | datetime | None = None, command: str = "") -> Record:
    """An event in the robot's life (a crash, a gearbox change), in the user's words.

    Parameters
    ----------
    identity : Identity
        The robot.
    note : str
        What happened; not empty (kept without leading and trailing spaces).
    time : str or datetime, optional
        When it happened (:func:`utc_time`); None (default): now.
    command : str, optional
        The command line (default '').

    Returns
    -------
    Record
        A record of kind "event".

    Raises
    ------
    ValueError
        When ``note`` is empty.

    Examples
    --------
    >>> from kincal.history import Identity, event_record
    >>> e = event_record(Identity("cell-3 arm"), "gearbox of joint 3 replaced ", "2024-05-03T12:00Z")
    >>> e.kind, e.time, e.note
    ('event', '2024-05-03T12:00:00.000000Z', 'gearbox of joint 3 replaced')
    """
    if not note.strip():
        raise ValueError("an event needs its description, e.g. --event 'gearbox of joint 3 replaced'")
    return Record(identity, "event", utc_time(time), note=note.strip(), payload=_about(command))
