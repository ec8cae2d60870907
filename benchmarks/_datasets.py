"""Where the benchmarks find the real datasets: used in place, ``../shared/datasets/<name>`` beside the checkout (or
beside any folder above it, or where KINCAL_SHARED_DATASETS points), never copied into the project."""
from __future__ import annotations

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def dataset(name: str) -> Path:
    """The folder of the shared dataset ``name`` (a clear error naming where it was looked for when absent)."""
    roots = [Path(os.environ["KINCAL_SHARED_DATASETS"])] if "KINCAL_SHARED_DATASETS" in os.environ else []
    roots += [parent / "shared" / "datasets" for parent in ROOT.parents]
    for root in roots:
        if (root / name).is_dir():
            return root / name
    raise SystemExit(f"the dataset '{name}' is not beside this checkout (looked in {', '.join(map(str, roots[:3]))}, "
                     f"…); set KINCAL_SHARED_DATASETS to the folder that holds it")


POSITIONER_MODEL = ROOT / "examples" / "positioner.yaml"  # the positioner's nominal model (kincal's own file)
