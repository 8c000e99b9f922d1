# Shared helpers of the rules: validation, sample sheet, code hash, input functions.
import sys

from imaging.ct_keys import RESOURCE_KEYS, resource_value
from imaging.packing.config import check_packings
from macro.config import check_ensembles, ensemble_cases, ensemble_members
from macro.laws import case_materials
from micro.config import (
    MATERIAL_KEYS,
    case_edge_length,
    check_studies,
    convergence_cases,
    realization_case,
    scale_realizations,
    source_names,
)
from shared.config import ConfigError, load_schema, sample_imaging, validate_config
from shared.errors import InputError
from shared.provenance import script_sha256
from shared.runs import run_folder
from shared.scan_sizes import check_scan_sizes, sample_point_spacing
from shared.table_export import check_csv_export

SCHEMA = load_schema(workflow.source_path("../schemas/config.schema.yaml"))
try:
    validate_config(
        config, SCHEMA, checks=[check_packings, check_studies, check_ensembles]
    )
except ConfigError as err:
    sys.exit(f"claychain: invalid configuration: {err}")


def scan_shape(name):
    """Voxel counts (z, y, x) of a sample's scan from the config or the file's headers;
    None when the file cannot be opened (its imaging job names the problem)."""
    entry = config["samples"][name]
    if entry["source"] == "phantom":
        return config["phantom"]["shape"]
    if entry["source"] == "raw" and "shape" in entry["raw"]:
        return entry["raw"]["shape"]
    # imported here: the readers' libraries (OpenCV, dask) only for a scan of a file
    from imaging.ct.io import ImageError, open_volume

    try:
        return open_volume(entry["source"], entry["path"]).shape
    except ImageError:
        return None


# the scan's extent against every micro case on it, before any job runs
try:
    check_scan_sizes(
        config,
        {
            name: shape
            for name in config["samples"]
            if (shape := scan_shape(name)) is not None
        },
        SCHEMA,
    )
except ConfigError as err:
    sys.exit(f"claychain: invalid configuration: {err}")

# every output, log and benchmark of the run under its folder (run_name, shared.runs)
RUN = run_folder(config)


def run_path(path):
    """``path`` inside the run's folder: ``results/<path>``, or
    ``results/<run_name>/<path>`` for a named run."""
    return f"{RUN}/{path}"


UPSCALING_TABLE = run_path("upscaling/pellet_permeability.nc")
# a hand edit of the table's CSV export would be ignored without a word; checked by the
# main process only (a job's own parse could fall between the table's and the export's
# writes of a running upscaling_table job)
if workflow.is_main_process:
    try:
        check_csv_export(UPSCALING_TABLE)
    except InputError as err:
        sys.exit(f"claychain: {err}")

SAMPLES = sorted(config["samples"])
CASES = sorted(config["micro"]["cases"])
PACKINGS = sorted(config["packings"])
REALIZATIONS = {r.name: r for r in scale_realizations(config)}
MACRO_CASES = sorted(config["macro"]["cases"])
# the members of the seed ensembles run as cases of their own (macro.ensembles)
MACRO_ENTRIES = {**config["macro"]["cases"], **ensemble_cases(config["macro"])}
ENSEMBLES = sorted(config["macro"]["ensembles"])


wildcard_constraints:
    sample="|".join(SAMPLES),
    case="|".join(CASES),
    packing="|".join(PACKINGS) or "(?!)",
    realization="|".join(REALIZATIONS) or "(?!)",
    macro_case="|".join(MACRO_ENTRIES) or "(?!)",
    ensemble="|".join(ENSEMBLES) or "(?!)",


# where the import walk found each module name, shared by the rules' script_code calls
_MODULE_LOOKUPS = {}


def script_code(script):
    """sha256 of the sources of our modules that a rule's script imports, transitively
    (shared.imports), a param: an edit of that code reruns the rule, other edits do not.
    """
    return script_sha256(
        workflow.source_path(f"../scripts/{script}"), lookups=_MODULE_LOOKUPS
    )


def get_point_spacing(wildcards):
    """``[edge, n_points]`` whose mean point spacing is the sample's default grid spacing:
    the smallest cube of the cases on the sample (shared.scan_sizes)."""
    return sample_point_spacing(config, wildcards.sample)


def get_sample_config(wildcards):
    """The configuration entry of a sample without its imaging settings (a param, so that
    its edits rerun the rule)."""
    return {
        key: value
        for key, value in config["samples"][wildcards.sample].items()
        if key != "imaging"
    }


def sample_settings(*keys):
    """Input function: these keys of the sample's imaging settings (``imaging`` with the
    sample's own keys merged over it), so that one sample's settings rerun it alone."""

    def settings(wildcards):
        imaging = sample_imaging(config, wildcards.sample, SCHEMA)
        return {key: imaging[key] for key in keys}

    return settings


def get_imaging_threads(wildcards):
    """Threads of a CT job: the sample's ``imaging.workers`` (a resource, not a param: the
    results do not depend on it, and changing it reruns nothing)."""
    return sample_settings("workers")(wildcards)["workers"]


def _imaging_resource(key):
    """Input function: a resource of a CT job, the sample's imaging ``key``
    (imaging.ct_keys.resource_value; a null key sets no resource)."""
    return lambda wildcards: resource_value(sample_settings(key)(wildcards)[key])


# the CT jobs' resources besides their threads: a change reruns nothing (docs/design.md §7)
IMAGING_RESOURCES = {key: _imaging_resource(key) for key in RESOURCE_KEYS[1:]}


def get_scan(wildcards):
    """The greyscale scan of a sample: its configured path, or the phantom's TIFF."""
    entry = config["samples"][wildcards.sample]
    if entry["source"] == "phantom":
        return run_path(f"phantom/{wildcards.sample}.tif")
    return entry["path"]


def get_slice_files(wildcards):
    """The files of a slice-folder scan, as inputs, so that editing one slice reruns the
    sample (a folder input alone is dated by its own entries, not by its files' content).
    """
    entry = config["samples"][wildcards.sample]
    if entry["source"] != "slices":
        return []
    # imported here: the reader's libraries (OpenCV, dask) only for a slice-folder sample
    from imaging.ct.io import ImageError, slice_files

    try:
        return [str(path) for path in slice_files(entry["path"])]
    except ImageError:  # the job itself refuses the folder, in one line
        return []


def get_packing_config(wildcards):
    """The configuration section of a packing (a param, so that its edits rerun it)."""
    return config["packings"][wildcards.packing]


def get_micro_porosity(wildcards):
    """The porosity grid that informs a micro case (a scale realization: its reference
    case): that of the case's own sample, else of micro.sample."""
    micro = config["micro"]
    if hasattr(wildcards, "realization"):
        entry = micro["cases"][micro["studies"]["scale"]["reference"]]
    else:
        entry = micro["cases"][wildcards.case]
    return run_path(f"porosity/{entry.get('sample', micro['sample'])}.nc")


def _micro_with_case(name, entry):
    """The micro settings with one case alone (a param: editing one case reruns it alone)."""
    # the studies only aggregate finished cases: declaring one reruns no case
    shared = {
        key: value
        for key, value in config["micro"].items()
        if key not in ("cases", "studies")
    }
    return {**shared, "cases": {name: entry}}


def get_micro_case_config(wildcards):
    """The micro settings with this case alone (its thread count is not a setting: the
    results do not depend on it, and changing it reruns nothing)."""
    entry = config["micro"]["cases"][wildcards.case]
    return _micro_with_case(
        wildcards.case, {k: v for k, v in entry.items() if k != "threads"}
    )


def get_micro_threads(wildcards):
    """Threads of this case's job (``micro.cases.<case>.threads``)."""
    return config["micro"]["cases"][wildcards.case].get("threads", 1)


def get_scale_realization_config(wildcards):
    """The micro settings with this realization of the scale study as its case."""
    realization = REALIZATIONS[wildcards.realization]
    return _micro_with_case(realization.name, realization_case(config, realization))


def get_micro_materials(wildcards):
    """The pellet's material section (a param: editing it reruns every micro case)."""
    pellet = config["materials"]["pellet"]
    return {"pellet": {key: pellet[key] for key in MATERIAL_KEYS}}


def get_upscaling_sources(wildcards):
    """Per condition, the micro results the pellet permeability table comes from."""
    folders = {"case": run_path("micro"), "realization": run_path("studies/scale")}
    return {
        condition: [f"{folders[kind]}/{name}.nc" for kind, name in sources]
        for condition, sources in source_names(config).items()
    }


def get_convergence_cases(wildcards):
    """The outputs of the convergence study's cases (micro.studies.convergence)."""
    cases = convergence_cases(config)
    if not cases:
        raise ValueError(
            "claychain: no convergence study: micro.studies.convergence is empty"
        )
    return expand(run_path("micro/{case}.nc"), case=cases)


def get_scale_inputs(wildcards):
    """The scale study's reference case and realizations (micro.studies.scale)."""
    if not REALIZATIONS:
        raise ValueError("claychain: no scale study: micro.studies.scale is empty")
    reference = config["micro"]["studies"]["scale"]["reference"]
    return {
        "reference": run_path(f"micro/{reference}.nc"),
        "realizations": expand(
            run_path("studies/scale/{realization}.nc"), realization=REALIZATIONS
        ),
    }


def get_scale_layout(wildcards):
    """The reference's edge and each realization (a param: a change reruns the aggregate)."""
    reference = config["micro"]["studies"]["scale"]["reference"]
    return {
        "reference": reference,
        "reference_edge_m": case_edge_length(config, reference),
        "realizations": [vars(r) for r in REALIZATIONS.values()],
    }


def get_macro_case_config(wildcards):
    """The macro settings with this case (or ensemble member) alone (a param: editing one
    case reruns it alone)."""
    # an ensemble only aggregates its members: declaring one reruns no other case
    shared = {
        key: value
        for key, value in config["macro"].items()
        if key not in ("cases", "ensembles", "threads")
    }
    return {
        **shared,
        "cases": {wildcards.macro_case: MACRO_ENTRIES[wildcards.macro_case]},
    }


def get_macro_threads(wildcards):
    """Threads of a macro job (``macro.threads``; not a param: the results do not
    depend on it)."""
    return config["macro"]["threads"]


def get_macro_materials(wildcards):
    """The mixture's material sections (Tables 4.1-4.2) with this case's own values, the
    only materials macro reads (a param: a case's own values rerun it alone)."""
    materials = case_materials(config["materials"], MACRO_ENTRIES[wildcards.macro_case])
    # keys sorted: the param does not depend on the order the config lists them in
    return {
        section: dict(sorted(values.items())) for section, values in materials.items()
    }


def get_ensemble_members(wildcards):
    """The results of a seed ensemble's members (macro.ensembles.<ensemble>)."""
    return expand(
        run_path("macro/{member}.nc"),
        member=ensemble_members(config["macro"], wildcards.ensemble),
    )


def get_ensemble_config(wildcards):
    """A seed ensemble's entry (a param: editing it reruns its statistics)."""
    return config["macro"]["ensembles"][wildcards.ensemble]


def get_macro_outputs():
    """One result and figure per macro case; the cases on one figure when there are several;
    the statistics of each seed ensemble (none by default)."""
    outputs = expand(
        [run_path("macro/{macro_case}.nc"), run_path("macro/{macro_case}.png")],
        macro_case=MACRO_CASES,
    )
    ensembles = expand(
        [
            run_path("macro/ensemble_{ensemble}.nc"),
            run_path("macro/ensemble_{ensemble}.png"),
        ],
        ensemble=ENSEMBLES,
    )
    comparison = [run_path("macro/comparison.png")] if len(MACRO_CASES) > 1 else []
    return outputs + comparison + ensembles


def get_study_outputs():
    """The study products of the declared studies (none by default)."""
    outputs = []
    if convergence_cases(config):
        outputs += [
            run_path("studies/convergence.nc"),
            run_path("studies/convergence.png"),
        ]
    if REALIZATIONS:
        outputs += [run_path("studies/scale.nc"), run_path("studies/scale.png")]
    return outputs


def get_final_outputs():
    """Every product of the default run."""
    imaging = expand(
        [
            run_path("porosity/{sample}.nc"),
            run_path("porosity/{sample}.png"),
            run_path("rev/{sample}.nc"),
            run_path("rev/{sample}.png"),
        ],
        sample=SAMPLES,
    )
    micro = expand(
        [run_path("micro/{case}.nc"), run_path("micro/{case}.png")], case=CASES
    )
    packing = expand(
        [run_path("packing/{packing}.nc"), run_path("packing/{packing}.png")],
        packing=PACKINGS,
    )
    studies = get_study_outputs()
    upscaling = [
        run_path("upscaling/pellet_permeability.nc"),
        run_path("upscaling/pellet_permeability.csv"),
        run_path("upscaling/pellet_permeability.png"),
    ]
    return (
        imaging
        + micro
        + [run_path("micro/comparison.png")]
        + studies
        + upscaling
        + packing
        + get_macro_outputs()
    )
