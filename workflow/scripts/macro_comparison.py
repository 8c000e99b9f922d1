"""Snakemake glue: the macro cases on one figure."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
import _logging  # noqa: E402

from macro.figures import comparison_figure  # noqa: E402
from shared.io import read_dataset  # noqa: E402

sm = snakemake  # noqa: F821
_logging.setup(sm.log[0])
cases = {Path(path).stem: read_dataset(path) for path in sm.input.cases}
comparison_figure(cases, sm.output.figure)
