"""Where the real datasets are: used in place, ``../shared/datasets/<name>`` beside the checkout (or beside any
folder above it, or where KINCAL_SHARED_DATASETS points), never copied into the project. Shared by the tests
(through ``conftest``) and the benchmarks."""
import os
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def shared_dataset(name: str) -> Path:
    """The folder of the shared dataset ``name`` (FileNotFoundError naming where it looked when absent)."""
    roots = [Path(os.environ["KINCAL_SHARED_DATASETS"])] if "KINCAL_SHARED_DATASETS" in os.environ else []
    roots += [parent / "shared" / "datasets" for parent in ROOT.parents]
    for root in roots:
        if (root / name).is_dir():
            return root / name
    raise FileNotFoundError(f"the shared dataset '{name}' is not beside this checkout (looked in "
                            f"{', '.join(map(str, roots[:3]))}, …); set KINCAL_SHARED_DATASETS to its folder")


POSITIONER_MODEL = ROOT / "examples" / "positioner.yaml"  # the positioner's nominal model (kincal's own file)
