"""The negative-compliance rule, shared by both fits: a joint that bends against its load is not a
spring, so a compliance term that comes out negative describes something else; it is dropped and
the fit repeated without it, and the note says so with the estimate and its σ."""
from __future__ import annotations

from typing import Mapping, Sequence

from ..models.terms import TAU_REF


def negative_compliances(names: Sequence[str], estimates: Mapping[str, float], std: Mapping[str, float]
                         ) -> tuple[list[str], tuple[str, ...]]:
    """The fitted compliance parameters that came out negative, and a note for each (rad/(N·m))."""
    neg = [n for n in names if n.endswith(".compliance") and estimates[n] < 0.0]
    notes = tuple(f"{n.split('.')[0]}: compliance came out negative ({estimates[n] / TAU_REF:+.3g} rad/(N·m), "
                  f"σ {std[n] / TAU_REF:.2g}) and was dropped; the fit was repeated without it" for n in neg)
    return neg, notes
