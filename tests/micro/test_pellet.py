"""The checkpoint measurement of micro.pellet: the same record in the background as here."""

from __future__ import annotations

from concurrent.futures import Future

import numpy as np

from micro.pellet import SpecimenSpec, initial_state, measure_checkpoint
from tests._defaults import CLAY, DEM

SUCTION = 132.0e6


class LateExecutor:
    """An executor that runs its task only when asked: a worker process's executor pickles
    the task's arguments in a thread of its own, possibly after the caller went on."""

    def __init__(self) -> None:
        self.tasks: list[tuple[Future, object]] = []

    def submit(self, task) -> Future:
        future: Future = Future()
        self.tasks.append((future, task))
        return future

    def run(self) -> None:
        for future, task in self.tasks:
            future.set_result(task())


def _state():
    return initial_state(SpecimenSpec(edge_length=4e-3, n_points=216, seed=3), None, 0.3,
                         CLAY, DEM)


def test_a_background_measurement_solves_the_state_of_its_checkpoint():
    """The state moves on in place after the measurement was handed to the worker (points
    3 % apart, the water changed): the worker's permeabilities are still those of the
    checkpoint, as measured in this process."""
    here = _state()
    reference_volume = float(here.mesh.volumes.sum())
    expected = measure_checkpoint(here, SUCTION, reference_volume, CLAY).result()

    state = _state()
    executor = LateExecutor()
    measurement = measure_checkpoint(state, SUCTION, reference_volume, CLAY,
                                     executor=executor, background=True)
    assert measurement.in_background and not measurement.done()
    state.dem.positions *= 1.03
    state.saturation[:] = 1.0
    state.porosity[:] = 0.5
    executor.run()
    got = measurement.result()
    for name in ("permeability", "permeability_tensor"):
        np.testing.assert_array_equal(got[name], expected[name], err_msg=name)
    assert np.all(np.isfinite(expected["permeability"])) and np.all(expected["permeability"] > 0)
