"""Snakemake glue: build, analyse and write one packing."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
import _logging  # noqa: E402

from imaging.packing import run  # noqa: E402

sm = snakemake  # noqa: F821
_logging.setup(sm.log[0])
outputs = run.PackingOutputs(sm.output.result, sm.output.figure)
run.run(sm.params.section, sm.wildcards.packing, outputs, rule=sm.rule)
