"""shared.plain_state and shared.snapshot: objects to plain data and back, restart files
checked before use and set aside when they fail."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import pytest

from shared.plain_state import Decoder, Encoder
from shared.snapshot import read_snapshot, write_snapshot


@dataclass
class Part:
    values: np.ndarray
    label: str = "part"


@dataclass(frozen=True)
class Settings:
    size: float


@dataclass
class Counters:
    looked_up: int = 0
    cache: dict = field(default_factory=dict)


@dataclass
class Whole:
    settings: Settings
    counters: Counters
    part: Part | None = None
    pieces: tuple[float, ...] = ()
    history: list = field(default_factory=list)
    times: dict[str, float] = field(default_factory=dict)


def _whole() -> Whole:
    shared = np.arange(6.0).reshape(2, 3)
    whole = Whole(Settings(1.0), Counters(7, {(1, 2): object()}), Part(shared), (0.5, float("inf")),
                  [np.float32(1.5), np.float32(2.5)], {"a": float("nan")})
    whole.alias = shared  # an attribute no class declares, the same array as part.values
    whole.rows = [np.zeros((2, 2), dtype=np.int8), np.ones((2, 2), dtype=np.int8)]
    whole.flag = np.bool_(True)
    return whole


def _round_trip(whole: Whole, given: dict[str, object]) -> Whole:
    encoder = Encoder(given=given)
    tree = encoder.attributes(whole, "whole")
    arrays = {k: v.copy() for k, v in encoder.arrays.items()}
    return Decoder(arrays, given).build(Whole, tree, "whole")


def test_an_object_comes_back_with_its_types_values_and_shared_arrays():
    whole = _whole()
    settings, counters = Settings(1.0), Counters()
    back = _round_trip(whole, {"settings": settings, "counters": counters})
    assert type(back.part) is Part and back.part.label == "part"
    assert back.part.values is back.alias and back.part.values is not whole.part.values
    np.testing.assert_array_equal(back.alias, np.arange(6.0).reshape(2, 3))
    assert back.pieces == (0.5, float("inf")) and type(back.pieces) is tuple
    assert [type(v) for v in back.history] == [np.float32, np.float32] and back.history == [1.5, 2.5]
    assert [r.dtype for r in back.rows] == [np.int8, np.int8] and back.rows[1].tolist() == [[1, 1], [1, 1]]
    assert np.isnan(back.times["a"]) and back.flag is np.True_
    # the given objects: the frozen one as given, the mutable one a copy with the saved counter
    assert back.settings is settings
    assert back.counters.looked_up == 7 and counters.looked_up == 0
    assert list(vars(back)) == list(vars(whole))


@pytest.mark.parametrize("attribute, value, message", [
    ("added", {1, 2}, r"whole\.added: a builtins\.set cannot be saved"),
    ("added", Part(np.zeros(2)), r"whole\.added: a Part without a declared type"),
    ("added", np.array([None, 1]), r"whole\.added: an array of Python objects"),
    ("added", {1: 2.0}, r"whole\.added: a dict with keys other than strings"),
])
def test_a_value_a_snapshot_cannot_hold_is_an_error_naming_it(attribute, value, message):
    whole = _whole()
    setattr(whole, attribute, value)
    with pytest.raises(TypeError, match=message):
        Encoder(given=("settings", "counters")).attributes(whole, "whole")


def test_a_snapshot_of_another_digest_is_left_and_a_failed_one_set_aside_each_under_a_new_name(
        tmp_path, caplog):
    path = tmp_path / "s.npz"
    log = logging.getLogger("test.snapshot")
    write_snapshot(path, "one", {"n": 3}, {"x": np.arange(4)})
    assert read_snapshot(path, "one", lambda meta, arrays: (meta["n"], arrays["x"].sum()), log) == (3, 6)
    with caplog.at_level("INFO", logger="test.snapshot"):
        assert read_snapshot(path, "two", lambda meta, arrays: 1, log) is None
    assert path.is_file() and "another configuration or code" in caplog.text
    # content that does not fit the code (here a key it lacks) is set aside as well
    with caplog.at_level("WARNING", logger="test.snapshot"):
        assert read_snapshot(path, "one", lambda meta, arrays: meta["absent"], log) is None
    assert "does not fit the code (KeyError: 'absent')" in caplog.text
    (tmp_path / "s.npz.rejected").unlink()
    for count, name in enumerate(("s.npz.rejected", "s.npz.rejected-2"), start=1):
        path.write_bytes(b"%d" % count)
        assert read_snapshot(path, "one", lambda meta, arrays: 1, log) is None
        assert (tmp_path / name).read_bytes() == b"%d" % count and not path.exists()
