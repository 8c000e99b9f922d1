"""Snakemake glue: write the synthetic pellet scan."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
import _logging  # noqa: E402

from imaging import run  # noqa: E402

_logging.setup(snakemake.log[0])  # noqa: F821
run.phantom(snakemake.config, snakemake.wildcards.sample, snakemake.output[0])  # noqa: F821
