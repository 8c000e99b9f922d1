"""Snakemake glue: write the synthetic pellet scan."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
import _logging  # noqa: E402

from imaging.ct import run  # noqa: E402

sm = snakemake  # noqa: F821
_logging.setup(sm.log[0])
config = {key: sm.params[key] for key in ("phantom", "calibration", "sample")}
run.phantom(config, sm.wildcards.sample, sm.output[0])
