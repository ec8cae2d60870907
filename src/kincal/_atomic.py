"""Atomic file writes: a temporary file in the same folder, then a rename (a leaf module)."""
from __future__ import annotations

import os
from pathlib import Path


def write_text_atomic(path: str | os.PathLike, text: str, encoding: str = "utf-8") -> None:
    """Write a file via a temporary file and rename, so no half-written file is ever left."""
    with AtomicFile(path, encoding) as fh:
        fh.write(text)
        fh.keep()


def json_path_for(path: str | os.PathLike) -> Path:
    """Where a report's JSON goes: beside its HTML, the same name with .json.

    Parameters
    ----------
    path : str or os.PathLike
        The report's HTML file.

    Returns
    -------
    Path
        ``x.html`` (or ``.htm``, any case) -> ``x.json``; any other name gets .json added (``x`` ->
        ``x.json``).

    Raises
    ------
    ValueError
        For a name ending in .json: the page would be HTML under a JSON name, its numbers in ``x.json.json``.

    Examples
    --------
    >>> from kincal.report import json_path_for
    >>> json_path_for("reports/ur5.html").as_posix()
    'reports/ur5.json'
    >>> json_path_for("ur5-report").as_posix()
    'ur5-report.json'
    """
    path = Path(path)
    if path.suffix.lower() == ".json":
        raise ValueError(f"{path}: the report is an HTML page: give it a .html name (its numbers are written "
                         f"beside it as {path.with_suffix('.json').name})")
    return path.with_suffix(".json") if path.suffix.lower() in (".html", ".htm") else Path(f"{path}.json")


DATA_STREAMS: set[int] = set()  # the file descriptors of kincal's own output streams an output file was written into


def data_on_stdout() -> bool:
    """Whether an output file went into kincal's standard output (``-o /dev/stdout``): its messages then go to the
    standard error, so that the data stay what a reader of the stream expects."""
    return 1 in DATA_STREAMS


class AtomicFile:
    """A text file written through a temporary file beside ``path``: it appears at ``path`` (renamed)
    only when :meth:`keep` was called before the ``with`` block ends; else, or on an error, the
    temporary file is removed and ``path`` is untouched. A link is followed (the file it names is replaced, the link
    kept). A path that is no regular file (``/dev/null``, a named pipe) is not renamed over (as root that would
    replace the device with a file), nor is the file kincal's own output goes to (``/dev/stdout`` redirected to a
    file): the text is held and written into it at once when kept (into the output stream itself for the latter;
    what kincal says then goes to the standard error, :func:`data_on_stdout`)."""

    def __init__(self, path: str | os.PathLike, encoding: str = "utf-8") -> None:
        self.path, self.encoding, self._keep = Path(path), encoding, False
        self._tmp: str | None = None
        self._stream = _std_stream(self.path)
        if self._stream is None and (not self.path.exists() or self.path.is_file()):
            self.path = Path(os.path.realpath(self.path))  # a regular file (or a new one): the file a link names

    def __enter__(self):
        if self._stream is not None or self.path.exists() and not self.path.is_file():
            import io

            self._fh = io.StringIO()
            return self
        import tempfile  # loaded when a file is written, not when kincal is imported

        fd, self._tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", dir=self.path.parent or ".")
        self._fh = os.fdopen(fd, "w", newline="", encoding=self.encoding)
        return self

    def write(self, text: str) -> None:
        self._fh.write(text)

    def keep(self) -> None:
        self._keep = True

    def __exit__(self, exc_type, exc, tb) -> None:
        if self._tmp is None:  # a stream, a device or a pipe: written as it is, once, when kept
            if exc_type is None and self._keep:
                if self._stream is not None:
                    self._stream.write(self._fh.getvalue())
                    self._stream.flush()
                    DATA_STREAMS.add(self._stream.fileno())
                    return
                with open(self.path, "w", newline="", encoding=self.encoding) as fh:
                    fh.write(self._fh.getvalue())
            return
        try:
            self._fh.close()
            if exc_type is None and self._keep:
                mask = os.umask(0)  # (read by setting it: there is no other way)
                os.umask(mask)
                os.chmod(self._tmp, 0o666 & ~mask)  # mkstemp makes 0600; outputs get the usual permissions
                os.replace(self._tmp, self.path)
        finally:  # not renamed (not kept, an error, or the close, chmod or rename failed): no temporary left
            if os.path.exists(self._tmp):
                os.unlink(self._tmp)


def _std_stream(path: Path):
    """sys.stdout or sys.stderr when ``path`` is the file, pipe or terminal it writes to (``/dev/stdout``,
    ``/proc/self/fd/1``, or the file the shell redirected it to), else None."""
    import stat
    import sys

    try:
        here = os.stat(path)
    except OSError:
        return None
    for stream in (sys.stdout, sys.stderr):
        try:
            there, terminal = os.fstat(stream.fileno()), stream.isatty()
        except (AttributeError, OSError, ValueError):  # a stream without a file (a test's capture)
            continue
        if stat.S_ISCHR(here.st_mode) and not terminal:
            continue  # /dev/null and other devices: not a stream of kincal's even where its output goes there
        if (here.st_dev, here.st_ino) == (there.st_dev, there.st_ino):
            return stream
    return None
