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

_received: list = []  # (word, exit code) of a signal that came while loading


def run() -> int:
    """Load the command line with the signals handled, run it, and return its exit code."""
    signal.signal(signal.SIGINT, lambda signum, frame: _received.append(("interrupted", 130)))
    signal.signal(signal.SIGTERM, lambda signum, frame: _received.append(("terminated", 143)))
    if os.environ.get("KINCAL_PROGRESS"):
        sys.stderr.write("kincal: loading\n")
        sys.stderr.flush()
    from kincal.cli import Terminated, main, on_sigterm, stopped
    try:
        signal.signal(signal.SIGINT, signal.default_int_handler)  # from here a signal stops at once
        signal.signal(signal.SIGTERM, on_sigterm)
        if _received:
            return stopped(*_received[0])
        code = main()
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        return code
    except Terminated:
        return stopped("terminated", 143)
    except KeyboardInterrupt:  # between main's own handlers and here
        return stopped("interrupted", 130)
