"""Where the calibration store is: the --store flag, else the environment variable KINCAL_STORE, else
``store:`` in kincal's configuration file ($XDG_CONFIG_HOME/kincal/config.yaml, by default
~/.config/kincal/config.yaml); none of them: no store (recording is off)."""
from __future__ import annotations

import os
from pathlib import Path

ENV = "KINCAL_STORE"


def config_path() -> Path:
    """kincal's configuration file: $XDG_CONFIG_HOME/kincal/config.yaml (~/.config when the variable is unset).

    Returns
    -------
    Path
        The file's path (it need not exist).

    Examples
    --------
    >>> from kincal.history import config_path
    >>> config_path().parts[-2:]
    ('kincal', 'config.yaml')
    """
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base) / "kincal" / "config.yaml"


def store_url(given: str | None = None) -> str | None:
    """The store's path or URL: ``given``, else $KINCAL_STORE, else the configuration file's ``store:``.

    Parameters
    ----------
    given : str, optional
        The --store flag (a path, sqlite:///PATH or postgresql://…); wins when given.

    Returns
    -------
    str or None
        The store's path or URL, or None when none is set (recording is off).

    Raises
    ------
    ValueError
        Naming the configuration file, when it cannot be read or its ``store:`` is not a path or URL.

    Examples
    --------
    >>> from kincal.history import store_url
    >>> store_url("~/kincal/robots.db")
    '~/kincal/robots.db'
    """
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
    """How a user turns the store on, in one sentence.

    Returns
    -------
    str
        The sentence: the --store flag, the environment variable ``ENV`` or the configuration file.

    Examples
    --------
    >>> from kincal.history import how_to_set
    >>> print(how_to_set())
    give --store PATH (an SQLite file) or --store postgresql://USER@HOST/DATABASE, set KINCAL_STORE, or write
    'store: PATH' in .../kincal/config.yaml
    """
    return (f"give --store PATH (an SQLite file) or --store postgresql://USER@HOST/DATABASE, set {ENV}, or write "
            f"'store: PATH' in {config_path()}")
