"""Snakemake glue: permeability of all micro cases in one figure."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
import _logging  # noqa: E402

from micro.figures import comparison_figure  # noqa: E402
from shared.io import read_dataset  # noqa: E402

sm = snakemake  # noqa: F821
_logging.setup(sm.log[0])
comparison_figure({Path(p).stem: read_dataset(p, ["permeability"]) for p in sm.input}, sm.output.figure)
