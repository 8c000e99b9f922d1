"""Snakemake glue: hydrate one micro case (a configured case or a scale-study realization).

All of it is guarded: the measurement's worker process is spawned, and spawning runs
this file again (as Snakemake names it, without the ``snakemake`` object)."""

if __name__ == "__main__":
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
    import _logging
    import numba

    from micro import run

    sm = snakemake  # noqa: F821
    _logging.setup(sm.log[0])
    # the parallel mesh and force kernels use the job's threads, not every core per job
    numba.set_num_threads(sm.threads)
    config = {"micro": sm.params.micro, "materials": sm.params.materials}
    (case,) = sm.params.micro["cases"]
    run.run(config, case, sm.input.porosity, run.CaseOutputs(sm.output.result, sm.output.figure), rule=sm.rule)
