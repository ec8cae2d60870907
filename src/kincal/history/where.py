"""Where the calibration store is: the --store flag, else the environment variable KINCAL_STORE, else
``store:`` in kincal's configuration file ($XDG_CONFIG_HOME/kincal/config.yaml, by default
~/.config/kincal/config.yaml); none of them: no store (recording is off)."""
from __future__ import annotations

import os
from pathlib import Path

ENV = "KINCAL_STORE"


def config_path() -> Path:
    """kincal's configuration file: $XDG_CONFIG_HOME/kincal/config.yaml (~/.config when the variable is unset)."""
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base) / "kincal" / "config.yaml"


def store_url(given: str | None = None) -> str | None:
    """The store's path or URL: ``given`` (the --store flag), else $KINCAL_STORE, else the configuration file's
    ``store:``, else None (off). A configuration file that cannot be read is a ValueError naming it."""
    if given:
        return given
    if os.environ.get(ENV, "").strip():
        return os.environ[ENV].strip()
    path = config_path()
    if not path.is_file():
        return None
    import yaml

    try:
        config = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise ValueError(f"{path}: kincal's configuration file cannot be read ({' '.join(str(exc).split())}); "
                         f"fix it or remove it") from None
    value = config.get("store") if isinstance(config, dict) else None
    if value is None:
        return None
    if not isinstance(value, str) or not value.strip():
        raise ValueError(f"{path}: 'store:' must be a path or a database URL (e.g. store: ~/kincal/robots.db)")
    return value.strip()


def how_to_set() -> str:
    """How a user turns the store on, in one sentence."""
    return (f"give --store PATH (an SQLite file) or --store postgresql://USER@HOST/DATABASE, set {ENV}, or write "
            f"'store: PATH' in {config_path()}")
