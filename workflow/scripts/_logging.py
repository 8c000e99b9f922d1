"""Route a rule's Python logging and uncaught errors to its ``log:`` file.

An expected failure reaches the user as one line ``claychain: <message>`` on stderr; its
traceback goes to the job's log file only, for debugging. Expected are, by type alone
(shared/errors.py): any :class:`shared.errors.ClaychainError` (a bad input, a bad
config value, a diverging run, a results file that cannot be written: ``atomic_write``
names it), an ``OSError`` that says a file cannot be written (permission, read-only or
full file system) and a ``KeyboardInterrupt`` (Ctrl-C: the job stops with one line and
resumes from its last restart file when run again). Any other exception is a bug: it
keeps its traceback on stderr, and in the log file.
"""

from __future__ import annotations

import errno
import logging
import sys
from types import TracebackType

from shared.errors import ClaychainError
from shared.io import write_failure

_WRITE_ERRNOS = {errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOSPC, errno.EDQUOT}
_TRACEBACK_LOGGER = "claychain.traceback"
INTERRUPTED = "interrupted (Ctrl-C); run the same command again to resume from the last restart file"


def expected_message(value: BaseException) -> str | None:
    """The one-line message of an expected failure, or None for an unexpected one."""
    if isinstance(value, KeyboardInterrupt):
        return INTERRUPTED
    if isinstance(value, OSError) and value.errno in _WRITE_ERRNOS:
        return write_failure(str(value.filename or "a results file"), value)
    if isinstance(value, ClaychainError):
        return " ".join(str(value).split()) or type(value).__name__
    return None


def setup(log_path: str) -> None:
    """Send INFO logs to the rule's log file and to stderr; report uncaught exceptions.

    An expected failure prints ``claychain: <message>`` on stderr and its traceback to
    the log file only; an unexpected one prints its traceback to both.
    """
    traceback_log = logging.getLogger(_TRACEBACK_LOGGER)
    traceback_log.propagate = False

    def excepthook(kind: type[BaseException], value: BaseException, traceback: TracebackType | None) -> None:
        message = expected_message(value)
        traceback_log.error("%s: %s", kind.__name__, value, exc_info=(kind, value, traceback))
        if message is None:
            sys.__excepthook__(kind, value, traceback)
        else:
            print(f"claychain: {message}", file=sys.stderr, flush=True)

    sys.excepthook = excepthook
    try:
        file_handler = logging.FileHandler(log_path, mode="w")
    except OSError as err:
        message = expected_message(err) or f"cannot write the log {log_path}: {err}"
        print(f"claychain: {message}", file=sys.stderr, flush=True)
        raise SystemExit(1) from None
    formatter = logging.Formatter("%(asctime)s %(name)s %(levelname)s %(message)s")
    file_handler.setFormatter(formatter)
    traceback_log.handlers[:] = [file_handler]
    logging.basicConfig(
        level=logging.INFO, format="%(asctime)s %(name)s %(levelname)s %(message)s",
        handlers=[file_handler, logging.StreamHandler(sys.stderr)], force=True,
    )
    logging.getLogger("matplotlib").setLevel(logging.WARNING)
