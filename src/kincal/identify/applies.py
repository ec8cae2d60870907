"""Which options apply to which measurement kinds: one table and one check, so that an option the
data's kind does not use is refused with its reason instead of being ignored.

Every option of ``calibrate`` and ``evaluate`` (a :class:`FitOptions` field, or a setting of how the
files are read and what is written) is named here with the kinds that use it; an option not in the
table applies to every kind. With several files of several kinds, an option is accepted when at
least one of the kinds uses it (``--distance`` for the socket file of a points + sockets fit).
``tests/test_applies.py`` walks the command line's flags and fails on any flag that a kind neither
reads nor refuses.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, Mapping

from ..observe.files import KINDS  # noqa: F401 (the kinds this table speaks of; tests walk them)

OBSERVED = ("pose", "markers", "same-point", "plane")  # kinds fitted with their own σ and set-up parameters


@dataclass(frozen=True)
class Scope:
    """The kinds an option applies to, and why the others do not use it (completes 'it does not apply
    because …'); ``alone``: only when every file is of these kinds (the position fit's options: files of
    several kinds are fitted together, by the one fit all kinds share)."""

    kinds: tuple[str, ...]
    why: str
    alone: bool = False


def _points_alone(why: str) -> Scope:
    return Scope(("point",), why, alone=True)


SCOPES: dict[str, Scope] = {
    "f_scale": _points_alone("it scales the robust loss of position data in m; the other kinds' samples are scaled "
                             "by their stated σ"),
    "method": _points_alone("the particle swarm searches the position residual; position data alone are fitted with "
                            "particle swarms; other kinds, and files of several kinds together, are not yet"),
    "pso": _points_alone("the particle swarm searches the position residual"),
    "residual": Scope(("point", "pose"), "the joint-space residual inverts measured positions or poses"),
    "drift": Scope(("point", "pose", "markers"), "sockets and planes have no measuring instrument that could drift"),
    "plot": Scope(("point", "pose"), "the figures show each sample's 3-D position error; the report (--report) "
                                     "shows every kind"),
    "tracker_noise": _points_alone("the other kinds state their noise with --std-pos (and --std-rot)"),
    "covariate_cols": _points_alone("the other kinds' files are read without covariate columns yet"),
    "std_cols": _points_alone("the other kinds read σ from the columns std_pos and std_rot_mrad"),
    "base": Scope(("point", "pose", "markers"), "sockets and planes do not see the measurement frame (the base is "
                                                "a gauge freedom for them)"),
    "orientation": Scope(("pose",), "only pose files have orientation columns"),
    "refit_target": Scope(("pose",), "only a 6-D target has a frame of its own on the flange"),
    "rot_cols": Scope(("pose",), "only pose files have orientation columns"),
    "std_rot": Scope(("pose",), "only poses measure an orientation"),
    "std_pos": Scope(OBSERVED, "position files state σ per axis with --std-cols (measurement_std_x/y/z) or "
                               "the verdict's --tracker-noise"),
    "markers": Scope(("markers",), "only marker files have NAME.x/.y/.z columns"),
    "label_col": Scope(("same-point", "plane"), "only socket and plane files have a label column"),
    "group_col": Scope(("same-point",), "only socket files group their labels by placement"),
    "distance": Scope(("same-point",), "known distances are between socket labels"),
    "plane": Scope(("plane",), "known planes are for plane contacts"),
    "same_frame": Scope(("point", "pose", "markers"), "sockets and planes are not measured in a frame"),
    "xyz_cols": Scope(("point", "pose"), "only point and pose files have one x, y, z triple"),
}


def joint_unit_scopes(robot: str, joint_types: Iterable[str], files: str,
                      lengths: tuple[str, ...] = ()) -> dict[str, Scope]:
    """The scopes of the unit options (``length_unit``, ``angle_unit``) where the files hold joint values and no
    measured position: a unit that reads none of the robot's joints applies to no kind (but ``lengths``, whose
    other values, as known distances or planes, it reads).

    Parameters
    ----------
    robot : str
        The robot's name, as the reason names it.
    joint_types : iterable of str
        Its joints' types: "revolute" (read in the angle unit), "covariate" (as written), any other (a length).
    files : str
        The files of joint values, as the reason names them (e.g. "the poses CSV").
    lengths : tuple of str, optional
        The kinds whose other values the length unit reads (default none).

    Returns
    -------
    dict of str to Scope
        ``length_unit`` when no joint is a length, ``angle_unit`` when none is revolute (empty when both read a
        joint): a table to add to the command's own for :func:`refuse_inapplicable`.

    Examples
    --------
    >>> from kincal.identify.applies import joint_unit_scopes
    >>> list(joint_unit_scopes("scara", ["revolute", "revolute", "prismatic", "revolute"], "the poses CSV"))
    []
    >>> refuse_inapplicable(["point"], {"length_unit": "--length-unit"},
    ...                     joint_unit_scopes("ur5", ["revolute"] * 6, "the poses CSV"))
    Traceback (most recent call last):
    ...
    ValueError: --length-unit does not apply to point data: ur5 has no prismatic joint, so its joint values are
    angles alone (--angle-unit) and the poses CSV holds no other length; leave it out
    """
    types = [t for t in joint_types if t != "covariate"]
    out = {}
    if all(t == "revolute" for t in types):
        out["length_unit"] = Scope(lengths, f"{robot} has no prismatic joint, so its joint values are angles alone "
                                            f"(--angle-unit) and {files} holds no other length")
    if "revolute" not in types:
        out["angle_unit"] = Scope((), f"{robot} has no revolute joint, so its joint values are lengths alone "
                                      f"(--length-unit) and {files} holds no angle")
    return out


def refuse_inapplicable(kinds: Iterable[str], given: Mapping[str, str],
                        scopes: Mapping[str, Scope] | None = None) -> None:
    """Refuse an option that none of the data's kinds uses, instead of ignoring it.

    An option not in :data:`SCOPES` applies to every kind; with several kinds, an option is accepted
    when at least one of them uses it (or, for the position fit's options, when every file is of those
    kinds).

    Parameters
    ----------
    kinds : iterable of str
        The measurement kinds of the files (``"point"``, ``"pose"``, ``"markers"``, ``"same-point"``,
        ``"plane"``).
    given : mapping of str to str
        The options given: option name (a key of :data:`SCOPES`) to the flag as the user wrote it.
    scopes : mapping of str to Scope, optional
        The table judged against (default :data:`SCOPES`, that of calibrate and evaluate; a command of its own
        flags, as simulate, gives its own). A scope of no kinds is an option the command never uses.

    Raises
    ------
    ValueError
        For the first option in ``given`` that none of ``kinds`` uses, naming the flag, the kinds and why.

    Examples
    --------
    >>> from kincal.identify import refuse_inapplicable
    >>> refuse_inapplicable(["point"], {"drift": "--drift"})  # accepted: returns None
    >>> refuse_inapplicable(["plane"], {"drift": "--drift"})
    Traceback (most recent call last):
    ...
    ValueError: --drift does not apply to plane data: sockets and planes have no measuring instrument that
    could drift; leave it out (it applies to point, pose or markers data)
    """
    kinds = tuple(dict.fromkeys(kinds))
    for name, flag in given.items():
        scope = (SCOPES if scopes is None else scopes).get(name)
        if scope is None or (set(kinds) <= set(scope.kinds) if scope.alone else set(scope.kinds) & set(kinds)):
            continue
        where = (f" (it applies to {_either(scope.kinds, 'or')} data{' alone' if scope.alone else ''})"
                 if scope.kinds else "")
        raise ValueError(f"{flag} does not apply to {_either(kinds, 'and')} data: {scope.why}; leave it out{where}")


def _either(words: tuple[str, ...], joiner: str) -> str:
    return words[0] if len(words) == 1 else f"{', '.join(words[:-1])} {joiner} {words[-1]}"
