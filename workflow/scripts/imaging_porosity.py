"""Snakemake glue: greyscale scan -> porosity grid."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
import _logging  # noqa: E402

from imaging.ct import run  # noqa: E402

sm = snakemake  # noqa: F821
_logging.setup(sm.log[0])
run.porosity(
    sm.wildcards.sample, sm.params.sample, sm.params.imaging, sm.params.material, sm.params.micro_spacing,
    sm.input.scan, sm.output.image, sm.output.porosity, sm.output.figure, rule=sm.rule,
)
