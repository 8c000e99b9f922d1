"""Route a rule's Python logging and uncaught errors to its ``log:`` file.

An expected failure (a bad input, a bad config value, a diverging run, a results folder
that cannot be written) reaches the user as one line ``claychain: <message>`` on stderr;
its traceback goes to the job's log file only, for debugging. Expected are the
project's own error types (``ConfigError``, ``OutputError``, ``ImageError``,
``DivergenceError``: any exception class defined in our packages), a ``ValueError``
raised by a ``raise`` statement of our own code (validation naming the key or file at
fault; not a library's ValueError on one of our lines, such as numpy's "setting an
array element with a sequence" of a bug), and an ``OSError`` that says a file cannot be
written (permission, read-only or full file system). Any other exception is a bug: it
keeps its traceback on stderr, and in the log file.
"""

from __future__ import annotations

import dis
import errno
import logging
import os
import shutil
import sys
from types import TracebackType

_PACKAGES = ("imaging", "micro", "macro", "shared")
_WRITE_ERRNOS = {errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOSPC, errno.EDQUOT}
_TRACEBACK_LOGGER = "claychain.traceback"
_RAISE = dis.opmap["RAISE_VARARGS"]


def _ours(module: str | None) -> bool:
    return bool(module) and str(module).split(".")[0] in _PACKAGES


def _raised_by_us(traceback: TracebackType | None) -> bool:
    """Whether a ``raise`` statement of our packages raised the error: the innermost
    frame of the traceback runs our code and stopped on a RAISE_VARARGS instruction (a
    library call, C-level or not, leaves it on the call; multi-line statements and
    missing sources do not matter)."""
    last = None
    while traceback is not None:
        last, traceback = traceback, traceback.tb_next
    if last is None or not _ours(last.tb_frame.f_globals.get("__name__")):
        return False
    code = last.tb_frame.f_code.co_code
    return 0 <= last.tb_lasti < len(code) and code[last.tb_lasti] == _RAISE


def _atomic_write_target(traceback: TracebackType | None) -> str | None:
    """The file that ``shared.io.atomic_write`` was writing when the error was raised."""
    while traceback is not None:
        frame = traceback.tb_frame
        if (frame.f_code.co_name == "atomic_write"
                and frame.f_globals.get("__name__") == "shared.io"):
            return str(frame.f_locals.get("path"))
        traceback = traceback.tb_next
    return None


def _free_space(path: str) -> str:
    folder = os.path.dirname(os.path.abspath(path))
    while folder and not os.path.isdir(folder):
        folder = os.path.dirname(folder)
    try:
        return f"{shutil.disk_usage(folder).free / 1e6:.3g} MB free there"
    except OSError:
        return "free space unknown"


def expected_message(value: BaseException) -> str | None:
    """The one-line message of an expected failure, or None for an unexpected one."""
    text = " ".join(str(value).split()) or type(value).__name__
    target = _atomic_write_target(value.__traceback__)
    if isinstance(value, OSError) and value.errno in _WRITE_ERRNOS:
        target = target or str(value.filename or "a results file")
        reason = value.strerror or text
        return (f"cannot write {target}: {reason} ({_free_space(target)}; is the results "
                "folder read-only or full?)")
    if target is not None and isinstance(value, (OSError, RuntimeError)):
        # the netCDF library's errors (e.g. "NetCDF: HDF error" on a full disk) name no file
        return (f"cannot write {target}: {text} ({_free_space(target)}; is the results "
                "folder read-only or full?)")
    if isinstance(value, Exception) and _ours(type(value).__module__):
        return text
    if isinstance(value, ValueError) and _raised_by_us(value.__traceback__):
        return text
    return None


def setup(log_path: str) -> None:
    """Send INFO logs to the rule's log file and to stderr; report uncaught exceptions.

    An expected failure prints ``claychain: <message>`` on stderr and its traceback to
    the log file only; an unexpected one prints its traceback to both.
    """
    traceback_log = logging.getLogger(_TRACEBACK_LOGGER)
    traceback_log.propagate = False

    def excepthook(kind, value, traceback):  # type: ignore[no-untyped-def]
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
