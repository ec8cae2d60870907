"""The ``kincal`` command's entry point: Ctrl-C and SIGTERM end with one line and exit 130 / 143 from
the first moment, while Python is still loading kincal and its libraries (seconds on a busy machine).

A module of its own, outside the ``kincal`` package, because importing anything inside it loads numpy
first; this one sets the signal handlers, then loads and runs :func:`kincal.cli.main`.
"""
import os
import signal
import sys


class _Stop(BaseException):
    def __init__(self, code: int, word: str) -> None:
        super().__init__(word)
        self.code, self.word = code, word


def _raise(code: int, word: str):
    def handler(signum, frame):
        raise _Stop(code, word)
    return handler


def _quiet_from_here() -> None:
    """No traceback from a late signal while Python shuts down (atexit handlers, flushing)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)


def run() -> int:
    """Load the command line with the signals handled, run it, and return its exit code."""
    signal.signal(signal.SIGINT, _raise(130, "interrupted"))
    signal.signal(signal.SIGTERM, _raise(143, "terminated"))
    try:
        if os.environ.get("KINCAL_PROGRESS"):
            sys.stderr.write("kincal: loading\n")
            sys.stderr.flush()
        from kincal.cli import main
        signal.signal(signal.SIGINT, signal.default_int_handler)  # main handles them from here on
        code = main()
        _quiet_from_here()
        return code
    except _Stop as stop:
        _quiet_from_here()
        sys.stderr.write(f"kincal: {stop.word}; nothing half-written\n")
        return stop.code
    except KeyboardInterrupt:  # between main's own handlers and here
        _quiet_from_here()
        sys.stderr.write("kincal: interrupted; nothing half-written\n")
        return 130
