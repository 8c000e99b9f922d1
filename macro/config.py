"""The macro stage's configuration helpers, light: the workflow reads them to build its
DAG without importing the model.

A seed ensemble ``macro.ensembles.<name>: {case, seeds}`` runs its case once per seed as
the cases ``<name>_s<seed>``, its members (:func:`ensemble_cases`); its statistics are
:mod:`macro.ensemble`'s.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from shared.config import ConfigError, check_ordered_pair

__all__ = ["check_ensembles", "ensemble_cases", "ensemble_members", "member_name"]


def member_name(ensemble: str, seed: int) -> str:
    """The case name of an ensemble's member: ``<ensemble>_s<seed>``."""
    return f"{ensemble}_s{seed}"


def ensemble_members(macro: Mapping[str, Any], ensemble: str) -> list[str]:
    """The case names of an ensemble's members, in the order of its seeds."""
    return [member_name(ensemble, seed) for seed in macro["ensembles"][ensemble]["seeds"]]


def ensemble_cases(macro: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """Every member of the validated ``macro.ensembles`` as a case entry: its ensemble's
    case with the member's seed."""
    return {
        member_name(name, seed): {**macro["cases"][entry["case"]], "seed": seed}
        for name, entry in macro["ensembles"].items()
        for seed in entry["seeds"]
    }


def check_ensembles(config: Mapping[str, Any]) -> None:
    """An ensemble runs a declared case; its members' names and output name no case.

    Raises
    ------
    ConfigError
        Naming the key of ``macro.ensembles`` at fault.
    """
    macro = config.get("macro")
    if not macro:
        return
    cases = macro["cases"]
    for name, entry in macro["ensembles"].items():
        key = f"macro.ensembles.{name}"
        if entry["case"] not in cases:
            raise ConfigError(
                f"config key '{key}.case': {entry['case']!r} is not a case of macro.cases "
                f"(cases: {', '.join(sorted(cases))})"
            )
        taken = sorted(set(ensemble_members(macro, name)) & set(cases))
        if taken:
            raise ConfigError(
                f"config key '{key}.seeds': member {taken[0]!r} is also a case of macro.cases"
            )
        if f"ensemble_{name}" in cases:
            raise ConfigError(
                f"config key '{key}': the case ensemble_{name} would have the ensemble's "
                f"output (results/macro/ensemble_{name}.nc); rename one of them"
            )
        check_ordered_pair(entry["band_quantiles"], f"{key}.band_quantiles")
