"""Configuration: JSON-schema validation with defaults and messages that name the key.

A configuration file is read by :func:`read_config_file`: a missing or empty file, one
that is not a mapping, a YAML syntax error (with its line and column) and a key given
twice in one mapping (with both lines) are each refused in one line naming the file. The
schema's checks refuse NaN and infinities wherever a number is expected (JSON schema's
``minimum`` and ``exclusiveMinimum`` let NaN through: every comparison with it is false).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator, Mapping, MutableMapping
from pathlib import Path
from typing import Any

import jsonschema
import yaml
from jsonschema.exceptions import ValidationError
from jsonschema.protocols import Validator

from shared.errors import ConfigError
from shared.runs import RESULTS, STAGE_FOLDERS, drop_removed_entries

_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
"""libyaml's loader where PyYAML has it: the schema loads in 0.02 s instead of 0.18 s."""

__all__ = [
    "ConfigError",
    "load_schema",
    "validate_config",
    "load_config",
    "read_config_file",
    "default_config",
    "sample_imaging",
    "check_ordered_pair",
    "SCHEMA_PATH",
    "DEFAULT_CONFIG_PATH",
]

_ROOT = Path(__file__).resolve().parent.parent
SCHEMA_PATH = _ROOT / "workflow" / "schemas" / "config.schema.yaml"
DEFAULT_CONFIG_PATH = _ROOT / "config" / "config.yaml"

Check = Callable[[Mapping[str, Any]], None]


def _with_defaults(validator_class: type[Validator]) -> type[Validator]:
    """Extend a validator so that it fills in the schema's defaults as it validates, and
    refuses NaN and infinities where the schema expects a number."""
    validate_properties = validator_class.VALIDATORS["properties"]
    validate_type = validator_class.VALIDATORS["type"]

    def finite_type(validator: Validator, types: str | list[str], instance: object,
                    schema: Mapping[str, Any]) -> Iterator[ValidationError]:
        numeric = {"number", "integer"} & set([types] if isinstance(types, str) else types)
        if numeric and isinstance(instance, float) and not math.isfinite(instance):
            yield ValidationError(f"{instance} is not a finite number (NaN and infinities are refused)")
            return
        yield from validate_type(validator, types, instance, schema)

    def set_defaults(validator: Validator, properties: Mapping[str, Any], instance: object,
                     schema: Mapping[str, Any]) -> Iterator[ValidationError]:
        if isinstance(instance, MutableMapping):
            for name, subschema in properties.items():
                if "default" in subschema and name not in instance:
                    instance[name] = _copy(subschema["default"])
        yield from validate_properties(validator, properties, instance, schema)

    return jsonschema.validators.extend(validator_class, {"properties": set_defaults, "type": finite_type})


def _copy(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {k: _copy(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_copy(v) for v in value]
    return value


_Validator = _with_defaults(jsonschema.Draft202012Validator)


def load_schema(path: str | Path = SCHEMA_PATH) -> dict[str, Any]:
    """Read the YAML JSON-schema of the configuration."""
    with open(path) as handle:
        return yaml.load(handle, Loader=_LOADER)


def _key_path(error: jsonschema.ValidationError, prefix: str = "") -> str:
    path = ".".join([prefix] * bool(prefix) + [str(p) for p in error.absolute_path])
    if error.validator == "additionalProperties":
        instance, schema = error.instance, error.schema
        assert isinstance(instance, Mapping) and isinstance(schema, Mapping)  # the keyword checks objects only
        extra = sorted(set(instance) - set(schema.get("properties", {})))
        path = ".".join(filter(None, [path, extra[0] if extra else ""]))
        return f"unknown config key '{path}'"
    return f"config key '{path or '<root>'}'"


def validate_config(
    config: MutableMapping[str, Any],
    schema: Mapping[str, Any] | None = None,
    checks: Iterable[Check] = (),
) -> MutableMapping[str, Any]:
    """Validate a configuration in place, filling in defaults, then cross-check its fields.

    Parameters
    ----------
    config
        The configuration; the schema's defaults are written into it.
    schema
        The JSON schema (default: ``workflow/schemas/config.schema.yaml``).
    checks
        Further cross-field checks of the stages (e.g. the packings' geometry), each
        raising :class:`ConfigError`; they run after the checks of this module.

    Notes
    -----
    The entries an overlay set to null are removed first (:mod:`shared.runs`).

    Raises
    ------
    ConfigError
        With the dotted path of the first offending key and the reason.
    """
    schema = schema if schema is not None else load_schema()
    drop_removed_entries(config)
    validator = _Validator(schema)
    errors = sorted(validator.iter_errors(config), key=lambda e: list(e.absolute_path))
    if errors:
        first = errors[0]
        raise ConfigError(f"{_key_path(first)}: {first.message}")
    for check in (_check_run_name, _check_samples, _check_lengths, _check_micro, _check_upscaling, *checks):
        check(config)
    _check_case_materials(config, schema)
    for sample in config["samples"]:
        sample_imaging(config, sample, schema)
    return config


def _merged(base: Mapping[str, Any], override: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` with the keys of ``override`` replacing its own, mapping by mapping."""
    out = _copy(base)
    for key, value in override.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = _merged(out[key], value)
        else:
            out[key] = _copy(value)
    return out


def sample_imaging(
    config: Mapping[str, Any], sample: str, schema: Mapping[str, Any] | None = None
) -> dict[str, Any]:
    """The imaging settings of one sample: its ``samples.<name>.imaging`` keys merged over
    the ``imaging`` section (validated, defaults filled in).

    Raises
    ------
    ConfigError
        Naming ``samples.<name>.imaging.<key>`` if the merged settings are invalid.
    """
    schema = schema if schema is not None else load_schema()
    merged = _merged(config["imaging"], config["samples"][sample].get("imaging", {}))
    errors = sorted(_Validator(schema["properties"]["imaging"]).iter_errors(merged),
                    key=lambda e: list(e.absolute_path))
    if errors:
        raise ConfigError(f"{_key_path(errors[0], f'samples.{sample}.imaging')}: {errors[0].message}")
    _check_imaging(merged, f"samples.{sample}.imaging" if "imaging" in config["samples"][sample]
                   and config["samples"][sample]["imaging"] else "imaging")
    return merged


def _check_imaging(imaging: Mapping[str, Any], prefix: str) -> None:
    """The keys that a mask mode or an anchor choice requires."""
    mask, calibration = imaging["mask"], imaging["calibration"]
    if mask["mode"] == "cylinder" and mask["cylinder_radius_m"] is None:
        raise ConfigError(
            f"config key '{prefix}.mask.cylinder_radius_m': required by mask mode cylinder"
        )
    if calibration["anchors"] == "histogram_peaks":
        if calibration["peak_densities_kg_m3"] is None:
            raise ConfigError(
                f"config key '{prefix}.calibration.peak_densities_kg_m3': required by "
                "anchors histogram_peaks (the densities of the two peaks' phases)"
            )
        for key in ("grey_air", "grey_muscovite"):
            if calibration[key] is not None:
                raise ConfigError(
                    f"config key '{prefix}.calibration.{key}': anchors histogram_peaks "
                    "takes both anchors from the histogram; remove it or use air_muscovite"
                )


def _check_run_name(config: Mapping[str, Any]) -> None:
    """A run is not named like a folder of the unnamed run's outputs."""
    name = config.get("run_name")
    if name in STAGE_FOLDERS:
        raise ConfigError(
            f"config key 'run_name': {name!r} is a folder of the unnamed run's outputs "
            f"({RESULTS}/{name}/); choose another name"
        )


def _check_samples(config: Mapping[str, Any]) -> None:
    """A scan that is not the phantom needs its file or folder."""
    for name, entry in config["samples"].items():
        if entry["source"] != "phantom" and not entry["path"]:
            raise ConfigError(
                f"config key 'samples.{name}.path': required for a {entry['source']} scan"
            )


def _check_lengths(config: Mapping[str, Any]) -> None:
    """Voxel sizes and grid spacings within ``plausible_length_m`` (a unit slip otherwise)."""
    low, high = config["plausible_length_m"]
    lengths = {f"samples.{name}.voxel_size_m": entry["voxel_size_m"]
               for name, entry in config["samples"].items()}
    lengths["imaging.grid_spacing_m"] = config.get("imaging", {}).get("grid_spacing_m")
    for name, entry in config["samples"].items():
        lengths[f"samples.{name}.imaging.grid_spacing_m"] = entry.get("imaging", {}).get("grid_spacing_m")
    for key, value in lengths.items():
        if value is not None and not low <= value <= high:
            raise ConfigError(
                f"config key '{key}': {value:g} m is outside the plausible range of a CT scan "
                f"[{low:g}, {high:g}] m (a length in mm typed as m?); if it is right, widen "
                "plausible_length_m"
            )


def _check_micro(config: Mapping[str, Any]) -> None:
    """Cross-field checks of the micro section that the schema cannot express."""
    micro = config.get("micro")
    if not micro:
        return
    if micro["sample"] not in config["samples"]:
        raise ConfigError(f"config key 'micro.sample': {micro['sample']!r} is not a sample")
    for case, entry in micro["cases"].items():
        if entry.get("sample", micro["sample"]) not in config["samples"]:
            raise ConfigError(
                f"config key 'micro.cases.{case}.sample': {entry['sample']!r} is not a sample "
                f"(samples: {', '.join(sorted(config['samples']))})"
            )
    checkpoints = list(micro["checkpoints_suction_pa"])
    if any(later >= earlier for earlier, later in zip(checkpoints, checkpoints[1:], strict=False)):
        raise ConfigError(
            "config key 'micro.checkpoints_suction_pa': suctions must strictly decrease, "
            f"got {checkpoints}"
        )


def _check_upscaling(config: Mapping[str, Any]) -> None:
    """The table's sources are micro cases, and its suction range is ordered."""
    upscaling = config.get("upscaling")
    if not upscaling or not config.get("micro"):
        return
    for condition, source in upscaling["conditions"].items():
        if isinstance(source, Mapping):
            fractions = config["micro"]["studies"]["scale"]["fractions"]
            if not any(abs(f - source["scale_fraction"]) < 1e-9 for f in fractions):
                raise ConfigError(
                    f"config key 'upscaling.conditions.{condition}.scale_fraction': "
                    f"{source['scale_fraction']} is not a fraction of micro.studies.scale "
                    f"(fractions: {fractions})"
                )
            continue
        for case in [source] if isinstance(source, str) else source:
            if case not in config["micro"]["cases"]:
                raise ConfigError(
                    f"config key 'upscaling.conditions.{condition}': {case!r} is not a case "
                    f"of micro.cases (cases: {', '.join(sorted(config['micro']['cases']))})"
                )
    check_ordered_pair(upscaling["suction_range_pa"], "upscaling.suction_range_pa")


def check_ordered_pair(pair: Any, key: str) -> None:
    """A [low, high] setting with low < high.

    Raises
    ------
    ConfigError
        Naming ``key`` otherwise.
    """
    low, high = pair
    if not low < high:
        raise ConfigError(f"config key '{key}': need low < high, got {[low, high]}")


def _check_case_materials(config: MutableMapping[str, Any], schema: Mapping[str, Any]) -> None:
    """A case's own material values are keys of ``materials.pellet``, valid there."""
    if not config.get("micro"):
        return
    pellet_schema = schema["properties"]["materials"]["properties"]["pellet"]
    for case, entry in config["micro"]["cases"].items():
        merged = {**config["materials"]["pellet"], **entry["materials"]}
        for error in _Validator(pellet_schema).iter_errors(merged):
            key = error.path[0] if error.path else ""
            if error.validator == "additionalProperties":
                key = sorted(set(merged) - set(pellet_schema["properties"]))[0]
            raise ConfigError(
                f"config key 'micro.cases.{case}.materials.{key}': {error.message}"
            )


class _DuplicateKey(Exception):
    """A key given twice in one YAML mapping: the key and both lines."""


class _UniqueKeyLoader(_LOADER):  # type: ignore[misc, valid-type]  # libyaml's loader where built, else PyYAML's
    """The safe loader, refusing a key given twice in one mapping (PyYAML keeps the last)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        self.flatten_mapping(node)
        lines: dict[Any, int] = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            if not isinstance(key, str | int | float | bool):
                continue  # an unhashable key is the constructor's to refuse
            line = key_node.start_mark.line + 1
            if key in lines:
                raise _DuplicateKey(key, lines[key], line)
            lines[key] = line
        return dict(super().construct_mapping(node, deep))


def read_config_file(path: str | Path) -> dict[str, Any]:
    """The mapping a YAML configuration file holds (not validated).

    Raises
    ------
    ConfigError
        Naming the file: missing, empty, not a mapping, a YAML syntax error (with line
        and column) or a key given twice in one mapping (with both lines).
    """
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: no such configuration file")
    try:
        with open(path) as handle:
            loaded = yaml.load(handle, Loader=_UniqueKeyLoader)
    except _DuplicateKey as error:
        key, first, again = error.args
        raise ConfigError(f"{path}: key {key!r} is given twice, on lines {first} and {again}; "
                          "keep one") from None
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark or error.context_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
        raise ConfigError(f"{path}: not valid YAML: {where}{error.problem or error.context}") from None
    except (yaml.YAMLError, UnicodeDecodeError) as error:
        raise ConfigError(f"{path}: not a YAML configuration file ({' '.join(str(error).split())})") from None
    if loaded is None:
        raise ConfigError(f"{path}: the configuration file is empty")
    if not isinstance(loaded, dict):
        raise ConfigError(f"{path}: the configuration must be a mapping of keys, not a YAML "
                          f"{'list' if isinstance(loaded, list) else type(loaded).__name__}")
    return loaded


def load_config(
    path: str | Path, schema: Mapping[str, Any] | None = None, checks: Iterable[Check] = ()
) -> dict[str, Any]:
    """Read a YAML configuration file (:func:`read_config_file`) and validate it (defaults
    filled in, cross-checked)."""
    return dict(validate_config(read_config_file(path), schema, checks))


def default_config() -> dict[str, Any]:
    """The embedded default configuration (``config/config.yaml``), validated.

    Benchmarks and tests take their parameters from it, so that they run the model users
    run unless they say otherwise.
    """
    return load_config(DEFAULT_CONFIG_PATH)
