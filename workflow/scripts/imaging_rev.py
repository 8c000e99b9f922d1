"""Snakemake glue: REV and chord-length analyses."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
import _logging  # noqa: E402

from imaging.ct import run  # noqa: E402
from imaging.ct.settings import ScanResources  # noqa: E402
from imaging.ct_keys import job_resources  # noqa: E402

sm = snakemake  # noqa: F821
_logging.setup(sm.log[0])
config = {key: sm.params[key] for key in ("sample", "settings")}
# the machine resources: the job's threads and resources (imaging/ct_keys.py), never params
resources = ScanResources.from_mapping(job_resources(sm.threads, sm.resources))
inputs = run.RevInputs(sm.input.scan, sm.input.image, sm.input.porosity)
outputs = run.RevOutputs(sm.output.rev, sm.output.figure)
run.rev(config, sm.wildcards.sample, inputs, outputs, resources=resources, rule=sm.rule)
