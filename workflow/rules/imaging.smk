# CT stage (imaging/ct): greyscale -> calibrated density -> porosity grid; REV and chord
# lengths (imaging/morphology). Each rule's params hold every science key its script reads,
# the imaging keys from the one list of them (imaging/ct_keys.py); the machine resources
# (imaging.workers, chunk_mb, memory_limit_gb, dask_scheduler) are its threads and
# resources, never params, so that changing them reruns nothing (docs/design.md §7).
from imaging.ct_keys import POROSITY_KEYS, REV_KEYS


rule imaging_phantom:
    """Synthetic pellet scan (greyscale TIFF) for a sample of source phantom."""
    output:
        run_path("phantom/{sample}.tif"),
    params:
        code=script_code("imaging_phantom.py"),
        phantom=config["phantom"],
        sample=get_sample_config,
        # the phantom maps density to grey with the anchors that calibration inverts
        calibration=lambda wildcards: {
            key: sample_settings("calibration")(wildcards)["calibration"][key]
            for key in ("air_density_kg_m3", "muscovite_density_kg_m3")
        },
    conda:
        "../envs/claychain.yaml"
    log:
        run_path("logs/imaging_phantom/{sample}.log"),
    benchmark:
        run_path("benchmarks/imaging_phantom/{sample}.tsv")
    script:
        "../scripts/imaging_phantom.py"


rule imaging_porosity:
    """CT scan -> specimen mask -> calibrated density -> porosity grid and figure."""
    input:
        scan=get_scan,
        slices=get_slice_files,
    output:
        image=run_path("images/{sample}.nc"),
        porosity=run_path("porosity/{sample}.nc"),
        figure=report(
            run_path("porosity/{sample}.png"),
            caption="../report/porosity.rst",
            category="1. CT imaging",
            subcategory="{sample}",
        ),
    params:
        code=script_code("imaging_porosity.py"),
        sample=get_sample_config,
        imaging=sample_settings(*POROSITY_KEYS),
        # one phi_0: the calibration anchors the mean dry density at the pellet's
        # reference porosity, that of the retention and permeability laws
        material={
            key: config["materials"]["pellet"][key]
            for key in ("dry_density_kg_m3", "reference_porosity")
        },
        micro_spacing=get_point_spacing,
    threads: get_imaging_threads
    resources:
        **IMAGING_RESOURCES,
    conda:
        "../envs/claychain.yaml"
    log:
        run_path("logs/imaging_porosity/{sample}.log"),
    benchmark:
        run_path("benchmarks/imaging_porosity/{sample}.tsv")
    script:
        "../scripts/imaging_porosity.py"


rule imaging_rev:
    """REV of porosity and interface density, and chord lengths, of a sample's scan."""
    input:
        scan=get_scan,
        slices=get_slice_files,
        image=run_path("images/{sample}.nc"),
        porosity=run_path("porosity/{sample}.nc"),
    output:
        rev=run_path("rev/{sample}.nc"),
        figure=report(
            run_path("rev/{sample}.png"),
            caption="../report/rev.rst",
            category="1. CT imaging",
            subcategory="{sample}",
        ),
    params:
        code=script_code("imaging_rev.py"),
        sample=get_sample_config,
        settings=sample_settings(*REV_KEYS),
    threads: get_imaging_threads
    resources:
        **IMAGING_RESOURCES,
    conda:
        "../envs/claychain.yaml"
    log:
        run_path("logs/imaging_rev/{sample}.log"),
    benchmark:
        run_path("benchmarks/imaging_rev/{sample}.tsv")
    script:
        "../scripts/imaging_rev.py"
