"""Snakemake glue: greyscale scan -> porosity grid."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
import _logging  # noqa: E402

from imaging.ct import run  # noqa: E402
from imaging.ct.settings import ScanResources  # noqa: E402
from imaging.ct_keys import job_resources  # noqa: E402

sm = snakemake  # noqa: F821
_logging.setup(sm.log[0])
config = {key: sm.params[key] for key in ("sample", "imaging", "material", "micro_spacing")}
# the machine resources: the job's threads and resources (imaging/ct_keys.py), never params
resources = ScanResources.from_mapping(job_resources(sm.threads, sm.resources))
outputs = run.PorosityOutputs(sm.output.image, sm.output.porosity, sm.output.figure)
run.porosity(config, sm.wildcards.sample, sm.input.scan, outputs, resources=resources, rule=sm.rule)
