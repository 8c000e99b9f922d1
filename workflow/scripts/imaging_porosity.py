"""Snakemake glue: greyscale scan -> porosity grid."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(snakemake.scriptdir)))  # noqa: F821
import _logging  # noqa: E402

from imaging.ct import run  # noqa: E402
from imaging.ct.settings import PorositySettings, ScanResources  # noqa: E402
from imaging.ct_keys import job_resources  # noqa: E402

sm = snakemake  # noqa: F821
_logging.setup(sm.log[0])
settings = PorositySettings.from_config(sm.wildcards.sample, sm.params.imaging, sm.params.material,
                                        sm.params.micro_spacing)
# the machine resources: the job's threads and resources (imaging/ct_keys.py), never params
resources = ScanResources.from_mapping(job_resources(sm.threads, sm.resources))
outputs = run.PorosityOutputs(sm.output.image, sm.output.porosity, sm.output.figure)
run.porosity(sm.input.scan, sm.params.sample, settings, outputs, resources, rule=sm.rule)
