"""Building the DAG reads the configuration helpers only: no model, no numba."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# snakemake's command line in this process, then the heavy modules it holds at exit
_PROBE = """
import atexit, sys
HEAVY = ("numba", "llvmlite", "xarray", "matplotlib", "cv2", "dask", "scipy")
atexit.register(lambda: print("LOADED:", *sorted({m.split(".")[0] for m in sys.modules}
                                                  & set(HEAVY))))
from snakemake.cli import main
sys.argv = ["snakemake", "-n", "--cores", "1"]
main()
"""


def test_a_dry_run_on_the_default_config_imports_no_model(tmp_path):
    shutil.copy(ROOT / "Snakefile", tmp_path / "Snakefile")
    shutil.copytree(ROOT / "workflow", tmp_path / "workflow")
    shutil.copytree(ROOT / "config", tmp_path / "config")
    result = subprocess.run([sys.executable, "-c", _PROBE], cwd=tmp_path, capture_output=True,
                            text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "This was a dry-run" in result.stdout + result.stderr
    (loaded,) = [line for line in result.stdout.splitlines() if line.startswith("LOADED:")]
    assert loaded == "LOADED:", loaded
