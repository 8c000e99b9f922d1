"""shared.checkpointer: a saved state comes back with the wall time it had, a file of
another digest is not resumed, the cadence counts from the last save, and the digest
follows the configuration, the input files and the code."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import shared.checkpointer
import shared.snapshot
from shared.checkpointer import Checkpointer, run_digest, saved_wall_time


def _restore(meta, arrays):
    return meta["step"], arrays["field"]


def _saved(path: Path, wall_time: float = 7.0) -> Checkpointer:
    """A checkpointer that has saved step 3 and a field after ``wall_time`` seconds, 2.5 of
    them in phase ``flow``."""
    saving = Checkpointer(path, "digest")
    saving.clock.add("flow", 2.5)
    saving.wall_time = lambda: wall_time  # the wall time so far [s], as the run counts it
    saving.save({"step": 3}, {"field": np.arange(4.0) / 3.0})
    return saving


def test_a_saved_state_resumes_with_the_wall_time_it_had(tmp_path):
    path = tmp_path / "run.npz"
    _saved(path)
    assert saved_wall_time(path) == (7.0, {"flow": 2.5})
    resuming = Checkpointer(path, "digest")
    step, field = resuming.resume(_restore)
    assert step == 3 and field.tobytes() == (np.arange(4.0) / 3.0).tobytes()
    assert resuming.resumed and resuming.earlier == 7.0 and resuming.clock.seconds == {"flow": 2.5}
    # the earlier runs' time and this one's
    assert resuming.wall_time() >= 7.0
    resuming.finish()
    assert not path.exists()


def test_a_file_of_another_digest_is_left_and_not_resumed(tmp_path):
    path = tmp_path / "run.npz"
    _saved(path)
    other = Checkpointer(path, "another digest")
    assert other.resume(_restore) is None
    assert not other.resumed and other.earlier == 0.0 and path.is_file()
    assert Checkpointer(tmp_path / "absent.npz", "digest").resume(_restore) is None


def test_the_cadence_counts_from_the_last_save(tmp_path):
    checkpointer = Checkpointer(tmp_path / "run.npz", "digest", interval=10.0)
    checkpointer.last_save = time.monotonic() - 15.0
    assert checkpointer.due() and checkpointer.due(1.5) and not checkpointer.due(2.0)
    checkpointer.save({}, {})
    assert not checkpointer.due()
    checkpointer.last_save = time.monotonic() - 15.0
    checkpointer.restart_cadence()
    assert not checkpointer.due()
    # without an interval only the saves the stage asks for
    assert not Checkpointer(tmp_path / "run.npz", "digest").due()


def test_the_digest_follows_the_configuration_the_inputs_and_the_code(tmp_path):
    code = Path(shared.checkpointer.__file__)
    table = tmp_path / "table.nc"
    table.write_bytes(b"one table")
    digest = run_digest({"case": "a", "k": 1.0}, code, [table])
    assert digest == run_digest({"k": 1.0, "case": "a"}, code, [table])  # key order aside
    assert digest != run_digest({"case": "a", "k": 2.0}, code, [table])
    assert digest != run_digest({"case": "a", "k": 1.0}, Path(shared.snapshot.__file__), [table])
    table.write_bytes(b"another table")
    assert digest != run_digest({"case": "a", "k": 1.0}, code, [table])
