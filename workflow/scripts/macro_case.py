"""Snakemake glue: run one macro mock-up case."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
import _logging  # noqa: E402
import numba  # noqa: E402

from macro import run  # noqa: E402

sm = snakemake  # noqa: F821
_logging.setup(sm.log[0])
numba.set_num_threads(sm.threads)
config = {"macro": sm.params.macro, "materials": sm.params.materials}
run.run(config, sm.wildcards.macro_case, sm.input.table, run.CaseOutputs(sm.output.result, sm.output.figure),
        rule=sm.rule)
