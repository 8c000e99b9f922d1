"""Snakemake glue: the pellet permeability table from the micro cases."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
import _logging  # noqa: E402

from micro.upscaling import run  # noqa: E402

sm = snakemake  # noqa: F821
_logging.setup(sm.log[0])
inputs = {condition: list(sm.input[condition]) for condition in sm.params.upscaling["conditions"]}
outputs = run.TableOutputs(sm.output.table, sm.output.csv, sm.output.figure)
run.run(sm.params.upscaling, inputs, outputs, rule=sm.rule)
