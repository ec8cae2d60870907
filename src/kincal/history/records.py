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

from ..models.robot import TOOL_NAMES, Robot

KINDS = ("calibration", "evaluation", "check", "comparison", "event")
TIME_FORMAT = "%Y-%m-%dT%H:%M:%S.%fZ"  # UTC, microseconds always: the text sorts as the time does
HASH_DIGITS = 12  # nominal values rounded to 1e-12 (m, rad) in the model hash


def utc_time(value: str | datetime | None = None) -> str:
    """A time as the store's UTC ISO 8601 text ('2024-05-03T14:00:00.000000Z'); ``None``: now. A text or
    datetime without a zone is this computer's local time; a ValueError names a text that is no ISO 8601 time."""
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
    """The store's time text as an aware UTC datetime."""
    return datetime.strptime(text, TIME_FORMAT).replace(tzinfo=timezone.utc)


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
    """A robot as the user names it: ``name`` and ``serial`` ('' when none given), and ``model_hash``, the
    sha256 of its nominal model (:func:`model_hash`; '' for an event, which has no model)."""

    name: str
    serial: str = ""
    model_hash: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise ValueError("a robot in the store needs a name (the name given at calibration)")

    def to_dict(self) -> dict:
        return {"name": self.name, "serial": self.serial, "model_hash": self.model_hash}

    @classmethod
    def from_dict(cls, d: Mapping) -> "Identity":
        return cls(str(d["name"]), str(d.get("serial") or ""), str(d.get("model_hash") or ""))


@dataclass(frozen=True)
class InputFile:
    """An input file's fingerprint: its path as given, the sha256 of its bytes (hex) and its size (bytes)."""

    path: str
    sha256: str
    size: int

    def to_dict(self) -> dict:
        return {"path": self.path, "sha256": self.sha256, "size": self.size}

    @classmethod
    def from_dict(cls, d: Mapping) -> "InputFile":
        return cls(str(d["path"]), str(d["sha256"]), int(d["size"]))


def fingerprint(path: str | Path) -> InputFile:
    """The sha256 (read in 1 MiB blocks, any size) and size of the file ``path``."""
    digest, size = hashlib.sha256(), 0
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
            size += len(block)
    return InputFile(str(path), digest.hexdigest(), size)


def model_hash(robot: Robot) -> str:
    """sha256 of a canonical JSON of the robot's own nominal model: its structure, joint names and types, and
    its parameters' names, kinds and values rounded to 1e-12 (m, rad). The measurement frame (base) and the
    measured point (tool) are the set-up, not the robot: left out, so a moved tracker or reflector is no new
    model. Pass the nominal robot (a calibrated file's nominal values), not the calibrated one."""
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
    """One entry of a robot's history (SI: m, rad).

    identity    -- the robot; kind -- one of KINDS; time -- UTC ISO 8601 (:func:`utc_time`)
    verdict     -- "good", "suspect", "refused" (a calibration), a check's answer, or None
    inputs      -- the input files' fingerprints
    parameters  -- name -> value of every robot parameter of the model (a calibration)
    sigmas      -- name -> 1-σ of each fitted robot parameter (None: undetermined)
    identifiable -- the robot parameters the data determined (finite σ), in model order
    covariance  -- {"names": [...], "matrix": [[...]]} over ``identifiable``, or None
    figures     -- name -> value: training_mean, training_rms, training_max, training_n, heldout_mean, … (m)
    mounting    -- the tool point found against the declared one ({"tool_point", "declared_tool_point",
                   "text"}), or None
    covariates  -- name -> (low, high): the range of each covariate in the data (temperature in K, time in s)
    note        -- the user's words (an event's description)
    payload     -- any other JSON detail: the calibrated file's ``calibration`` section, the command line,
                   kincal's version, the parameters' kinds
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
        return {"identity": self.identity.to_dict(), "kind": self.kind, "time": self.time, "verdict": self.verdict,
                "inputs": [i.to_dict() for i in self.inputs], "parameters": dict(self.parameters),
                "sigmas": dict(self.sigmas), "identifiable": list(self.identifiable), "covariance": self.covariance,
                "figures": dict(self.figures), "mounting": self.mounting,
                "covariates": {k: list(v) for k, v in self.covariates.items()}, "note": self.note,
                "payload": self.payload}

    @classmethod
    def from_dict(cls, d: Mapping) -> "Record":
        return cls(Identity.from_dict(d["identity"]), str(d["kind"]), str(d["time"]), d.get("verdict"),
                   tuple(InputFile.from_dict(i) for i in d.get("inputs") or ()), dict(d.get("parameters") or {}),
                   dict(d.get("sigmas") or {}), tuple(d.get("identifiable") or ()), d.get("covariance"),
                   dict(d.get("figures") or {}), d.get("mounting"),
                   {k: tuple(v) for k, v in (d.get("covariates") or {}).items()}, str(d.get("note") or ""),
                   dict(d.get("payload") or {}))


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


def calibration_record(result: Any, identity: Identity, inputs: Iterable[InputFile],
                       heldout: Iterable[Any] | None = None, note: str = "", command: str = "",
                       covariates: Mapping | None = None, time: str | datetime | None = None) -> Record:
    """The record of a :class:`kincal.CalibrationResult`: every robot parameter's value, the fitted ones' σ,
    the identifiable set (finite σ) and its covariance, the verdict, the training figures (the kept poses of
    position data, else every set's position statistics) and the ``heldout`` ones (EvaluationStats or sets'
    statistics dicts, m), the mounting, ``covariates`` (name -> (low, high)) and, in the payload, the calibrated
    file's ``calibration`` section. ``time``: now when None."""
    robot = result.robot
    sigmas = {n: _finite(result.std.get(n)) for n in result.names}
    ident = tuple(n for n in robot.params.names if sigmas.get(n) is not None)
    at = [result.free.index(n) for n in ident]
    covariance = {"names": list(ident), "matrix": result.covariance[np.ix_(at, at)]} if ident else None
    figures = _combined([result.stats_after] if result.data else result.per_set, "training")
    figures |= _combined(heldout or (), "heldout")
    mounting = None if not result.mounting else {
        "tool_point": robot.tool_point(), "declared_tool_point": result.nominal.tool_point(), "text": result.mounting}
    payload = _about(command, robot) | {"estimated": list(result.names), "calibration": json_safe(result.record())}
    return Record(identity, "calibration", utc_time(time), result.verdict.status, tuple(inputs),
                  robot.params.as_dict(), sigmas, ident, covariance, figures, mounting, dict(covariates or {}), note,
                  payload)


def evaluation_record(stats: Any, identity: Identity, inputs: Iterable[InputFile], note: str = "",
                      command: str = "", covariates: Mapping | None = None, time: str | datetime | None = None,
                      robot: Robot | None = None) -> Record:
    """The record of an evaluation: ``stats`` (one :class:`kincal.EvaluationStats` or a statistics dict per
    file, m) as its held-out figures (data the model was not fitted on), each file's statistics in the payload;
    ``robot``: the model evaluated (its parameters' kinds in the payload)."""
    parts = list(stats) if isinstance(stats, (list, tuple)) else [stats]
    figures = _combined(parts, "heldout")
    details = [dict(p) if isinstance(p, Mapping) else p.to_dict() for p in parts]
    return Record(identity, "evaluation", utc_time(time), None, tuple(inputs), figures=figures,
                  covariates=dict(covariates or {}), note=note,
                  payload=_about(command, robot) | {"evaluation": json_safe(details)})


def event_record(identity: Identity, note: str, time: str | datetime | None = None, command: str = "") -> Record:
    """An event in the robot's life (a crash, a gearbox change) at ``time`` (now when None), in the user's words."""
    if not note.strip():
        raise ValueError("an event needs its description, e.g. --event 'gearbox of joint 3 replaced'")
    return Record(identity, "event", utc_time(time), note=note.strip(), payload=_about(command))
