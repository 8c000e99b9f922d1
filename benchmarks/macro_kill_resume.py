"""A macro run killed three times resumes to the uninterrupted result, bit for bit.

``python -m benchmarks run macro_kill_resume [--size MAX_STEPS]`` runs the default
configuration's first macro case (``MAX_STEPS`` lowers ``macro.numerics.max_steps``) on
the synthetic pellet permeability table of ``benchmarks.macro``, uninterrupted in this
process, then as a user's run in a process of its own, SIGKILLed from this one three
times (once its snapshot holds a step before the first remesh, and after two later
ones: the kill lands wherever the next step is) and rerun from its snapshot each time.
The remesh steps come from the uninterrupted result's records (their step and remesh
count), at the records' resolution; nothing of the model is patched. It
records the kill points, the snapshot resumed from, the wall times, and whether the
result and the ParaView series are the uninterrupted run's, bit for bit, naming what
differs. The kill points and the snapshot setting: docs/performance.md,
"benchmarks.macro_kill_resume".

``python -m benchmarks.macro_kill_resume CONFIG TABLE OUTPUT`` is the user's run
(configuration as JSON).
"""

from __future__ import annotations

import copy
import json
import logging
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import xarray as xr

from benchmarks.macro import synthetic_table
from benchmarks.parameters import CONFIG
from shared.io import write_dataset
from shared.snapshot import read_meta

__all__ = ["bench_macro_kill_resume"]

ROOT = Path(__file__).resolve().parents[1]
VARYING = ("runtime_s", "resumed", "created", "history", "code_version", "source")
"""Attributes of a result that tell when and how fast it was made, not what (the code
version carries a dirty mark when the tree is edited while the runs go on)."""


def _remesh_steps(result: xr.Dataset) -> list[int]:
    """The steps of the records at which the remesh count grew: each at or after a
    remesh, before the next record's step."""
    count, step = result["remesh_count"].values, result["step"].values
    return [int(k) for k in step[1:][np.diff(count) > 0]]


def _uninterrupted(config: dict, case: str, table: Path, output: Path) -> xr.Dataset:
    """The run uninterrupted in this process, with the user's configuration (its
    snapshots included, so that the provenance's configuration is the same); its result."""
    import macro.run

    macro.run.run(config, case, table, macro.run.CaseOutputs(output))
    return xr.load_dataset(output)


def _user_run(config: Path, table: Path, output: Path, kill_at: int) -> tuple[int, float]:
    """The user's run in a process of its own (its log on this one's stderr), SIGKILLed
    from here as soon as its snapshot (one after every step) holds step ``kill_at``:
    the kill lands wherever the next step happens to be (-1: never killed). Its exit
    code and wall time [s]."""
    start = time.monotonic()
    child = subprocess.Popen([sys.executable, "-m", "benchmarks.macro_kill_resume", str(config),
                              str(table), str(output)], cwd=output.parent,
                             env={**os.environ, "PYTHONPATH": str(ROOT)}, stdout=subprocess.DEVNULL)
    while kill_at >= 0 and child.poll() is None:
        try:
            if _snapshot(output)[0] >= kill_at:
                child.kill()
                break
        except OSError:  # not written yet
            pass
        time.sleep(0.02)
    code = child.wait()
    return code, time.monotonic() - start


def _snapshot(output: Path) -> tuple[int, int]:
    """Step and remesh count of the run's snapshot."""
    model = read_meta(output.with_name(f".{output.stem}.snapshot.npz"))["model"]
    return int(model["steps"]), int(model["counters"]["object"]["remeshes"])


def _differences(whole: xr.Dataset, resumed: xr.Dataset) -> list[str]:
    """Names of the variables, coordinates and attributes that differ bit for bit."""
    names = sorted(set(whole.variables) | set(resumed.variables))
    differ = [n for n in names if n not in whole.variables or n not in resumed.variables
              or not whole[n].identical(resumed[n])]
    keys = {k for ds in (whole, resumed) for k in ds.attrs
            if k not in VARYING and not k.startswith("seconds_")}
    return differ + sorted(f"attrs.{k}" for k in keys
                           if not np.array_equal(np.asarray(whole.attrs.get(k)), np.asarray(resumed.attrs.get(k))))


def _series(folder: Path, name: str) -> dict[str, bytes]:
    """The files of a ParaView series, the collection named ``case.pvd``."""
    return {p.name.replace(name, "case"): p.read_bytes() for p in folder.iterdir()} if folder.is_dir() else {}


def bench_macro_kill_resume(max_steps: int | None = None) -> dict:
    """The default macro case SIGKILLed before the first remesh and after two others,
    resumed each time, against the uninterrupted run (bit for bit)."""
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    config = copy.deepcopy(CONFIG)
    numerics = config["macro"]["numerics"]
    numerics["snapshot_interval_s"] = 1e-9
    if max_steps is not None:
        numerics["max_steps"] = int(max_steps)
    case = sorted(config["macro"]["cases"])[0]
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        table = write_dataset(synthetic_table(), tmp / "table.nc", stage="upscaling", title="synthetic")
        start = time.monotonic()
        whole = _uninterrupted(config, case, table, tmp / "whole.nc")
        whole_s = time.monotonic() - start
        steps = int(whole.attrs["steps"])
        remeshed = _remesh_steps(whole)
        third = len(remeshed) // 3
        if len(remeshed) >= 3:
            kills = [remeshed[0] // 2, remeshed[third], remeshed[2 * third]]
        else:
            # a run that never remeshes (confined pellets): a quarter, half and three quarters in
            kills = [steps // 4, steps // 2, 3 * steps // 4]
        if len(kills) < 3 or len(set(kills)) < 3 or kills[0] < 1 or kills[-1] >= steps:
            raise ValueError(f"{steps} steps with remeshes at steps {remeshed}: too few for three "
                             "kill points; raise the max_steps (--size)")
        config_path = tmp / "config.json"
        config_path.write_text(json.dumps(config, default=str))
        output = tmp / "resumed.nc"
        runs = []
        for kill_at in (*kills, -1):
            code, wall = _user_run(config_path, table, output, kill_at)
            if code != (0 if kill_at < 0 else -signal.SIGKILL):
                raise RuntimeError(f"the user's run (kill at step {kill_at}) exited with {code}; "
                                   "its log is above")
            if kill_at < 0:
                runs.append({"kill_at": None, "exit_code": code, "wall_s": wall})
                break
            snapshot_step, snapshot_remeshes = _snapshot(output)
            runs.append({"kill_at": kill_at, "exit_code": code, "wall_s": wall,
                         "snapshot_step": snapshot_step, "snapshot_remeshes": snapshot_remeshes})
        resumed = xr.load_dataset(output)
        differ = _differences(whole, resumed)
        vtk_identical = (_series(tmp / "whole_vtk", "whole") == _series(tmp / "resumed_vtk", "resumed"))
    return {
        "macro_case": case,
        "table": "synthetic (benchmarks.macro.synthetic_table)",
        "max_steps": int(numerics["max_steps"]),
        "n_pellets": int(whole.attrs["n_pellets"]),
        "steps": steps,
        "stop_reason": whole.attrs["stop_reason"],
        "simulated_s": float(whole["time"][-1]),
        "remeshes": int(whole.attrs["remeshes"]),
        "remesh_steps": remeshed,
        "kills": kills,
        "uninterrupted_wall_s": whole_s,
        "runs": runs,
        "resumed": int(resumed.attrs["resumed"]),
        "bit_identical": not differ and vtk_identical,
        "differences": differ,
        "vtk_series_identical": vtk_identical,
    }


def main() -> None:
    """The user's run: ``CONFIG TABLE OUTPUT``, as its Snakemake job runs it."""
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    config, table, output = sys.argv[1:]
    import macro.run

    settings = json.loads(Path(config).read_text())
    macro.run.run(settings, sorted(settings["macro"]["cases"])[0], table, macro.run.CaseOutputs(output))


if __name__ == "__main__":
    main()
