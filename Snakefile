# claychain: CT scan -> porosity grid -> micro pellet model -> upscaling -> macro mock-up.
# Run:   snakemake --cores 2            (config/config.yaml, validated at start)
# Rerun one stage:  snakemake --cores 2 -R imaging_rev -U imaging_rev
from snakemake.utils import min_version

min_version("9.0")


configfile: "config/config.yaml"


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/imaging.smk"
include: "workflow/rules/micro.smk"
include: "workflow/rules/packing.smk"
include: "workflow/rules/upscaling.smk"
include: "workflow/rules/macro.smk"


rule all:
    """Every product of the configured run (config/config.yaml by default)."""
    input:
        get_final_outputs(),
    default_target: True
