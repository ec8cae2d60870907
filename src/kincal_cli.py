"""The ``kincal`` command's entry point: Ctrl-C and SIGTERM end with one line and exit 130 / 143 from
the first moment, while Python is still loading kincal and its libraries (seconds on a busy machine).

A module of its own, outside the ``kincal`` package, because importing anything inside it loads numpy
first. While the libraries load, a signal is only remembered (an exception raised inside a C
extension's import would surface as a confusing ImportError) and acted on as soon as loading ends;
from then on it stops the command at once.
"""
import os
import signal
import sys

_received: list = []  # (exit code, word) of a signal that came while loading


class _Stop(BaseException):
    def __init__(self, code: int, word: str) -> None:
        super().__init__(word)
        self.code, self.word = code, word


def _remember(code: int, word: str):
    def handler(signum, frame):
        _received.append((code, word))
    return handler


def _raise(code: int, word: str):
    def handler(signum, frame):
        raise _Stop(code, word)
    return handler


def _stopped(code: int, word: str) -> int:
    """One line; no traceback from a later signal while Python shuts down."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    sys.stderr.write(f"kincal: {word}; nothing half-written\n")
    return code


def run() -> int:
    """Load the command line with the signals handled, run it, and return its exit code."""
    signal.signal(signal.SIGINT, _remember(130, "interrupted"))
    signal.signal(signal.SIGTERM, _remember(143, "terminated"))
    if os.environ.get("KINCAL_PROGRESS"):
        sys.stderr.write("kincal: loading\n")
        sys.stderr.flush()
    from kincal.cli import main
    try:
        signal.signal(signal.SIGINT, signal.default_int_handler)  # from here a signal stops at once
        signal.signal(signal.SIGTERM, _raise(143, "terminated"))
        if _received:
            return _stopped(*_received[0])
        code = main()
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        return code
    except _Stop as stop:
        return _stopped(stop.code, stop.word)
    except KeyboardInterrupt:  # between main's own handlers and here
        return _stopped(130, "interrupted")
