"""Snakemake glue: greyscale scan -> porosity grid."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
import _logging  # noqa: E402

from imaging.ct import run  # noqa: E402
from imaging.ct_keys import job_settings  # noqa: E402

sm = snakemake  # noqa: F821
_logging.setup(sm.log[0])
# the science settings (params) with the job's threads and resources (imaging/ct_keys.py)
settings = job_settings(sm.params.imaging, sm.threads, sm.resources)
run.porosity(
    sm.wildcards.sample, sm.params.sample, settings, sm.params.material, sm.params.micro_spacing,
    sm.input.scan, sm.output.image, sm.output.porosity, sm.output.figure, rule=sm.rule,
)
