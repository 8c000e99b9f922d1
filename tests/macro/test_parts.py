"""The macro model's parts declare what they read of each other.

Each part of :class:`macro.model.MacroModel` (a mixin) lists in ``READS`` the model's
attributes and the other parts' methods it uses; the lists are checked against the
parts' code, so they cannot drift, and against the model, so every declared name exists.
"""

import ast
import dataclasses
import inspect
import textwrap

import pytest

from macro.model import MacroModel
from macro.parts import Counters
from macro.state import ModelState

PARTS = [base for base in MacroModel.__mro__[1:] if base.__module__.startswith("macro.") and base is not ModelState]


def _self_attributes(cls: type) -> set[str]:
    tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    return {node.attr for node in ast.walk(tree)
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "self"}


def test_the_model_is_composed_of_the_six_parts():
    assert {part.__name__ for part in PARTS} == {
        "Geometry", "Hydraulics", "Extrusion", "PressureVolume", "Mechanics", "WallReadings"}


@pytest.mark.parametrize("part", PARTS, ids=lambda part: part.__name__)
def test_a_part_declares_exactly_what_it_reads_of_the_others(part):
    own = {name for name, value in vars(part).items() if callable(value) or isinstance(value, property)}
    assert set(part.READS) == _self_attributes(part) - own - {"READS"}


@pytest.mark.parametrize("part", PARTS, ids=lambda part: part.__name__)
def test_what_a_part_reads_the_model_holds(part):
    fields = {f.name for f in dataclasses.fields(MacroModel)}
    missing = [name for name in part.READS if name not in fields and not hasattr(MacroModel, name)]
    assert not missing


def test_the_counters_become_the_results_attributes_by_name():
    counters = Counters(remeshes=3, extruded_volume_m3=1.5)
    counters.phase_seconds["dem"] = 2.0
    attributes = counters.attributes()
    assert attributes["remeshes"] == 3 and attributes["extruded_volume_m3"] == 1.5
    assert attributes["seconds_dem"] == 2.0 and "phase_seconds" not in attributes
    assert len(attributes) == len(dataclasses.fields(Counters)) - 1 + len(counters.phase_seconds)
