"""Where the benchmarks find the real datasets: the tests' own lookup (``tests/shared_data.py``), used in place,
never copied into the project."""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from shared_data import POSITIONER_MODEL, shared_dataset as dataset  # noqa: E402

__all__ = ["POSITIONER_MODEL", "dataset"]
