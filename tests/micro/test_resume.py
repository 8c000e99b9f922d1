"""A micro run killed after any checkpoint and resumed writes the uninterrupted run's netCDF.

The kill is simulated as in ``test_hydration.py``: ``advance_to_balance`` raises at the
checkpoint after the kill point, so the run stops with its checkpoint file on disk, and
a second call resumes from it. The case: 216 points and four checkpoints from 132 MPa
to 0.1 MPa (33 saves between flow steps, 18 remeshes). On 216 points and six
checkpoints, the code before the flow numbering and the solver's reuse state were saved
differed after a kill at the fifth checkpoint (gas permeability tensor 3 %, porosity
histogram), and at 1000 points after the sixth of 14 (issue 14).
"""

from __future__ import annotations

import copy
import json
import os
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import xarray as xr

import micro.case as micro_case
import micro.pool as micro_pool
import micro.run as micro_run
from micro.hydration import DivergenceError
from shared.checkpointer import saved_wall_time
from shared.config import validate_config
from shared.solver import SPDSolver

from .porosity_grid import write_porosity_grid

CHECKPOINTS = [132.0e6, 20.0e6, 1.0e6, 1.0e5]

# attributes that legitimately differ between two runs of the same case: the time of
# writing (``created``, ``history``) and what the run cost (``wall_time_s``: the
# resumed run counts the killed run's time up to its checkpoint file, and
# ``peak_memory_mb``)
VOLATILE = {"created", "history", "wall_time_s", "peak_memory_mb"}


@pytest.fixture(scope="module", autouse=True)
def _no_case_figure():
    """The runs here skip the case figure (about a second of matplotlib each): the tests
    compare netCDFs, and ``test_figures.py`` checks the figure."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(micro_run.figures, "case_figure", lambda ds, case, path: Path(path))
        yield


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    """The configuration of a 216-point CT case and its porosity grid."""
    tmp = tmp_path_factory.mktemp("resume")
    config = validate_config({
        "samples": {"p": {"source": "phantom", "voxel_size_m": 3e-4}},
        # a snapshot after every flow step: the kills between flow steps below
        "micro": {"sample": "p", "specimen_size_m": 4e-3, "n_points": 216,
                  "snapshot_interval_s": 0.0,
                  "checkpoints_suction_pa": CHECKPOINTS, "cases": {"c": {"porosity": "ct"}}},
        "upscaling": {"conditions": {"free": "c", "confined": "c"}},
    })
    return config, write_porosity_grid(tmp / "porosity.nc", 4e-4), tmp


@pytest.fixture(scope="module")
def uninterrupted(case):
    config, grid, tmp = case
    output = tmp / "uninterrupted.nc"
    micro_run.run(config, "c", grid, micro_run.CaseOutputs(output, tmp / "uninterrupted.png"))
    return output


def _assert_same_file(resumed: Path, reference: Path) -> None:
    with xr.open_dataset(reference) as a, xr.open_dataset(resumed) as b:
        assert sorted(a.variables) == sorted(b.variables)
        for name in a.variables:  # every data variable and coordinate, bit for bit
            x, y = a[name].values, b[name].values
            assert x.dtype == y.dtype and x.shape == y.shape, name
            if x.dtype.kind == "f":
                assert np.array_equal(x.view(np.uint64 if x.itemsize == 8 else np.uint32),
                                      y.view(np.uint64 if y.itemsize == 8 else np.uint32)), name
            else:
                assert np.array_equal(x, y), name
            assert a[name].attrs == b[name].attrs, name
        same = {k: v for k, v in a.attrs.items() if not _volatile(k)}
        assert same == {k: v for k, v in b.attrs.items() if not _volatile(k)}
        assert VOLATILE <= set(b.attrs)


def _volatile(attribute: str) -> bool:
    """Provenance times and the wall time in all and per phase (``wall_time_<phase>_s``)."""
    return attribute in VOLATILE or attribute.startswith("wall_time_")


@pytest.mark.parametrize("kill", range(1, len(CHECKPOINTS)))
def test_resume_after_a_kill_at_every_checkpoint_is_bit_identical(case, uninterrupted, kill,
                                                                   monkeypatch):
    config, grid, tmp = case
    output = tmp / f"killed_after_{kill}.nc"
    original = micro_case.advance_to_balance
    calls = {"n": 0}

    def killed(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == kill + 1:
            raise DivergenceError("simulated kill")
        return original(*args, **kwargs)

    monkeypatch.setattr(micro_case, "advance_to_balance", killed)
    with pytest.raises(DivergenceError, match="simulated kill"):
        micro_run.run(config, "c", grid, micro_run.CaseOutputs(output, output.with_suffix(".png")))
    state_file = output.with_suffix(".checkpoint.npz")
    before, phases = saved_wall_time(state_file)
    assert before > 0.0 and not output.exists()
    monkeypatch.setattr(micro_case, "advance_to_balance", original)
    resumed = micro_run.run(config, "c", grid, micro_run.CaseOutputs(output, output.with_suffix(".png")))
    assert not state_file.exists()
    # the whole run: the killed run's time up to its checkpoint file, and the rest; the
    # phases partition it and carry the killed run's share over
    assert resumed.attrs["wall_time_s"] > before
    timed = {k[len("wall_time_"):-2]: v for k, v in resumed.attrs.items()
             if k.startswith("wall_time_") and k != "wall_time_s"}
    assert set(phases) <= set(timed) and all(timed[k] >= v for k, v in phases.items())
    assert {"settling", "flow", "relaxation", "measurement"} <= set(timed)
    assert sum(timed.values()) <= resumed.attrs["wall_time_s"]
    _assert_same_file(output, uninterrupted)


@pytest.mark.parametrize("kill", [1, 25])
def test_resume_after_a_kill_between_flow_steps_is_bit_identical(case, uninterrupted, kill,
                                                                  monkeypatch):
    """Killed just after the ``kill``-th save between two flow steps (mid-balance: the
    first, on the way to the second checkpoint, and one near the middle of the last
    checkpoint's balance), the run resumes from that file and writes the uninterrupted
    run's netCDF."""
    config, grid, tmp = case
    output = tmp / f"killed_in_balance_{kill}.nc"
    original = micro_case.save_checkpoint
    saves = {"n": 0}

    def killed(*args, **kwargs):
        original(*args, **kwargs)
        if kwargs.get("balance") is not None:
            saves["n"] += 1
            if saves["n"] == kill:
                raise DivergenceError("simulated kill")

    monkeypatch.setattr(micro_case, "save_checkpoint", killed)
    with pytest.raises(DivergenceError, match="simulated kill"):
        micro_run.run(config, "c", grid, micro_run.CaseOutputs(output, output.with_suffix(".png")))
    state_file = output.with_suffix(".checkpoint.npz")
    with np.load(state_file) as data:
        balance = json.loads(str(data["meta"]))["balance"]
    assert balance is not None and balance["flow_steps"] >= 1
    monkeypatch.setattr(micro_case, "save_checkpoint", original)
    micro_run.run(config, "c", grid, micro_run.CaseOutputs(output, output.with_suffix(".png")))
    _assert_same_file(output, uninterrupted)


def test_the_saves_between_flow_steps_change_nothing(case, uninterrupted):
    """The same case without saves between flow steps gives the same variables bit for bit."""
    config, grid, tmp = case
    quiet = copy.deepcopy(config)
    quiet["micro"]["snapshot_interval_s"] = 1e9
    output = tmp / "no_snapshots.nc"
    micro_run.run(quiet, "c", grid, micro_run.CaseOutputs(output, output.with_suffix(".png")))
    with xr.open_dataset(uninterrupted) as a, xr.open_dataset(output) as b:
        for name in a.data_vars:
            np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)


@pytest.mark.parametrize("interval, worker_done", [(0.0, True), (1e9, True), (1e9, False)])
def test_measurements_in_a_worker_process_change_nothing(case, uninterrupted, interval,
                                                         worker_done, monkeypatch):
    """With the worker process forced (spawned, as from 100 000 cells on two threads),
    the run writes the uninterrupted run's variables bit for bit whichever way its
    checkpoints are measured: with a save due at every flow step, each in both processes
    at once, then saved; never saving before the end, all but the last in the worker
    while the next checkpoint hydrates; with a worker that seems to lag (still busy at
    the next checkpoint), that next one in both processes, then saved, and so on
    alternately."""
    import numba

    from micro.pellet import CheckpointMeasurement

    config, grid, tmp = case
    configured = copy.deepcopy(config)
    configured["micro"]["snapshot_interval_s"] = interval
    monkeypatch.setattr(micro_pool, "MEASUREMENT_PROCESS_CELLS", 0)
    monkeypatch.setattr(numba, "get_num_threads", lambda: 2)
    monkeypatch.setattr(CheckpointMeasurement, "done", lambda self: worker_done)
    submitted = []
    original = micro_case.measure_checkpoint

    def counted(*args, **kwargs):
        submitted.append(kwargs["executor"] is not None and kwargs["background"])
        return original(*args, **kwargs)

    monkeypatch.setattr(micro_case, "measure_checkpoint", counted)
    output = tmp / f"worker_{interval:g}_{worker_done}.nc"
    micro_run.run(configured, "c", grid, micro_run.CaseOutputs(output, output.with_suffix(".png")))
    n = len(CHECKPOINTS)
    expected = ([False] * n if interval == 0.0 else
                [worker_done or i % 2 == 0 for i in range(n - 1)] + [False])
    assert submitted == expected
    if interval == 0.0:
        _assert_same_file(output, uninterrupted)
    else:
        with xr.open_dataset(uninterrupted) as a, xr.open_dataset(output) as b:
            for name in a.data_vars:
                np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)


def test_the_thread_count_changes_nothing(case, uninterrupted):
    """The same case on one numba thread (the kernels, the Delaunay repair's groups)
    writes the variables of the run on all threads bit for bit."""
    import numba

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has a single thread here")
    config, grid, tmp = case
    output = tmp / "one_thread.nc"
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        micro_run.run(config, "c", grid, micro_run.CaseOutputs(output, output.with_suffix(".png")))
    finally:
        numba.set_num_threads(before)
    with xr.open_dataset(uninterrupted) as a, xr.open_dataset(output) as b:
        for name in a.data_vars:
            np.testing.assert_array_equal(a[name].values, b[name].values, err_msg=name)


KILLED_RUN = """
import os
import time

import numba

from micro import pool

if __name__ == "__main__":
    pool.MEASUREMENT_PROCESS_CELLS = 0
    numba.get_num_threads = lambda: 2
    with pool.measurement_executor(1) as executor:
        print(executor.submit(os.getpid).result(), flush=True)
        executor.submit(time.sleep, 600.0)
        time.sleep(600.0)
"""


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie does not: nothing may reap it here)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:
        return False
    return "\nState:\tZ" not in status


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads /proc (Linux)")
def test_a_killed_run_leaves_no_measurement_worker(tmp_path):
    """SIGKILL the run's process while its worker solves (sleeps, here): the worker
    exits within a few of its polling intervals instead of finishing its task."""
    import signal
    import subprocess
    import sys
    import time

    script = tmp_path / "killed_run.py"
    script.write_text(KILLED_RUN)
    root = Path(micro_run.__file__).parents[1]
    # the context closes the stdout pipe (a ResourceWarning otherwise) and waits
    with subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True,
                          cwd=root, env={**os.environ, "PYTHONPATH": str(root)}) as run:
        try:
            worker = int(run.stdout.readline())
            assert _alive(worker)
        finally:
            run.send_signal(signal.SIGKILL)
    deadline = time.monotonic() + 20 * micro_pool.WORKER_PARENT_POLL_S + 10.0
    while _alive(worker) and time.monotonic() < deadline:
        time.sleep(0.1)
    alive = _alive(worker)
    if alive:
        os.kill(worker, signal.SIGKILL)
    assert not alive


def _laplacian(n: int, shift: float) -> sp.csc_matrix:
    main = np.full(n, 2.0 + shift)
    full = sp.diags([main, -np.ones(n - 1), -np.ones(n - 1)], [0, -1, 1], format="csc")
    lower = sp.tril(full, format="csc")
    lower.sort_indices()
    return lower


@pytest.mark.parametrize("growth", [2.0, 1.05])
def test_a_restored_solver_continues_bit_for_bit(growth):
    """Counters (back-off, buy-at-once, stale iterations) and the factor: the restored
    solver takes the same refactoring decisions and gives the same bits. Doubling the
    shift makes the solver buy at once with a back-off; growing it by 5 % makes the
    next solve rent the stale (refactored on restoring) factor."""
    rng = np.random.default_rng(2)
    n = 400
    rhs = [rng.standard_normal(n) for _ in range(12)]
    matrices = [_laplacian(n, 1e-3 * growth**k) for k in range(12)]
    original = SPDSolver(refactor_iterations=6)
    for k in range(4):
        original.solve(matrices[k], rhs[k], ordered=True)
    scalars, arrays = original.reuse_state()
    assert arrays
    if growth == 2.0:
        assert scalars["buy_at_once"] > 0 and scalars["backoff"] > 1
    else:
        assert scalars["buy_at_once"] == 0
    restored = SPDSolver(refactor_iterations=6)
    restored.restore_reuse_state(scalars, arrays)
    assert json.dumps(restored.reuse_state()[0]) == json.dumps(scalars)
    factored = restored.stats.factorisations
    for k in range(4, 12):
        a = original.solve(matrices[k], rhs[k], ordered=True)
        b = restored.solve(matrices[k], rhs[k], ordered=True)
        np.testing.assert_array_equal(a.view(np.uint64), b.view(np.uint64))
        if k == 4 and growth < 2.0:  # solved with the factor rebuilt on restoring
            assert restored.stats.factorisations == factored
    assert json.dumps(restored.reuse_state()[0]) == json.dumps(original.reuse_state()[0])
