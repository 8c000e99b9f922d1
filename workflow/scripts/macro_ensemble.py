"""Snakemake glue: the statistics of a macro seed ensemble."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
import _logging  # noqa: E402

from macro import ensemble  # noqa: E402

sm = snakemake  # noqa: F821
_logging.setup(sm.log[0])
outputs = ensemble.EnsembleOutputs(sm.output.result, sm.output.figure)
ensemble.run(sm.params.ensemble, sm.wildcards.ensemble, sm.input.members, outputs, rule=sm.rule)
