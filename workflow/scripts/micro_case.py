"""Snakemake glue: hydrate one micro case (a configured case or a scale-study realization).

The main code is guarded: the measurement's worker process (spawned) imports this
script again, and must not rerun the case."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
import _logging  # noqa: E402
import numba  # noqa: E402

from micro import run  # noqa: E402

if __name__ == "__main__":
    sm = snakemake  # noqa: F821
    _logging.setup(sm.log[0])
    # the parallel mesh and force kernels use the job's threads, not every core per job
    numba.set_num_threads(sm.threads)
    config = {"micro": sm.params.micro, "materials": sm.params.materials}
    (case,) = sm.params.micro["cases"]
    run.run(config, case, sm.input.porosity, sm.output.result, sm.output.figure, rule=sm.rule)
