"""Route a rule's Python logging and uncaught errors to its ``log:`` file."""

from __future__ import annotations

import logging
import sys


def setup(log_path: str) -> None:
    """Send INFO logs to the rule's log file and to stderr; log uncaught exceptions too."""
    handlers = [logging.FileHandler(log_path, mode="w"), logging.StreamHandler(sys.stderr)]
    logging.basicConfig(
        level=logging.INFO, format="%(asctime)s %(name)s %(levelname)s %(message)s",
        handlers=handlers, force=True,
    )
    logging.getLogger("matplotlib").setLevel(logging.WARNING)

    def excepthook(kind, value, traceback):  # type: ignore[no-untyped-def]
        logging.getLogger("claychain").error("%s: %s", kind.__name__, value)
        sys.__excepthook__(kind, value, traceback)

    sys.excepthook = excepthook
