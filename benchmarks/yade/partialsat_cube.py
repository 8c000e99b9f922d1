# ruff: noqa: F821  (Yade injects O, Sphere, flow and its engine classes as globals)
"""Yade 2023.02a side of the Yade comparison benchmark: the micro model's cube.

Run headless as ``yade -x -n -j1 partialsat_cube.py SETTINGS.json``. ``SETTINGS.json``
(written by :mod:`benchmarks.yade_compare`) names the points file (``x y z r`` per
line, metres) and the output files, and holds the Table 3.1 clay parameters, the DEM
parameters and the run lengths; the few numbers set here are those of Appendix .2
that our model does not have (wall material, porosity clamps, swelling floor).

After Caulk (2022) Appendix .2 with the corrections of docs/yade.md §10: spheres in six
walls with PartialSatClayEngine, equilibration at the initial suction, water
permeability along x (wall flux) at that state, saturated and along the settings'
curve, then timings of coupled iterations and remeshes. The steps in full:
docs/performance.md, "benchmarks.yade.partialsat_cube". The script runs inside Yade's
interpreter, whose namespace provides ``O``, the engine and functor classes and ``utils``.
"""

import json
import sys
import time

import numpy as np

WALL_OFFSET = 1e-3  # walls 1 mm away from the packing, as the thesis's free swelling run


def read_settings():
    """Load the settings JSON named on the command line."""
    if len(sys.argv) != 2:
        raise SystemExit("usage: yade -x -n -j1 partialsat_cube.py SETTINGS.json")
    with open(sys.argv[1]) as handle:
        return json.load(handle)


def build_scene(settings):
    """Walls (bodies 0-5, where the flow engine expects them), spheres and engines."""
    dem = settings["dem"]
    O.reset()
    O.materials.append(PartialSatMat(
        density=dem["density"], young=dem["young_modulus"], poisson=dem["poisson_ratio"],
        frictionAngle=np.radians(dem["friction_angle_deg"]), label="spheres",
    ))
    # Appendix .2's wall material: very stiff, frictionless.
    O.materials.append(PartialSatMat(
        density=0, young=8.8e13, poisson=0.8, frictionAngle=0.0, label="walls",
    ))
    data = np.loadtxt(settings["points_path"], ndmin=2)
    low = (data[:, :3] - data[:, 3:4]).min(axis=0)
    high = (data[:, :3] + data[:, 3:4]).max(axis=0)
    O.bodies.append(aabbWalls([Vector3(*low), Vector3(*high)], thickness=0, material="walls"))
    for x, y, z, r in data:
        O.bodies.append(sphere((x, y, z), r, material="spheres"))
    # aabbWalls order is x-, x+, y-, y+, z-, z+; move each one outwards.
    for wall in range(6):
        axis, side = divmod(wall, 2)
        position = Vector3(O.bodies[wall].state.pos)
        position[axis] += WALL_OFFSET if side else -WALL_OFFSET
        O.bodies[wall].state.pos = position
    O.engines = [
        ForceResetter(),
        InsertionSortCollider([Bo1_Sphere_Aabb(aabbEnlargeFactor=1.0), Bo1_Box_Aabb()]),
        InteractionLoop(
            [
                Ig2_Sphere_Sphere_ScGeom6D(interactionDetectionFactor=1.0),
                Ig2_Box_Sphere_ScGeom6D(),
            ],
            [Ip2_PartialSatMat_PartialSatMat_MindlinPhys()],
            [Law2_ScGeom_MindlinPhys_Mindlin(includeAdhesion=False)],
        ),
        PartialSatClayEngine(label="flow"),
        NewtonIntegrator(gravity=(0, 0, 0), damping=dem["damping"]),
    ]
    O.dt = dem["time_step"]
    O.dynDt = False
    return data.shape[0]


def configure_flow(settings):
    """Table 3.1 parameters, pressure boundaries at the initial suction, solver knobs."""
    clay = settings["clay"]
    suction = clay["initial_suction"]
    flow.blockIsoCells = False
    flow.useSolver = 4
    flow.numSolveThreads = 1
    flow.numFactorizeThreads = 1
    flow.multithread = False  # aborts or zeroes saturation after a background remesh
    flow.meshUpdateInterval = -1  # remesh only when asked: the timings choose when
    flow.defTolerance = -1
    flow.viscosity = clay["water_viscosity"]
    flow.airViscosity = clay["gas_viscosity"]
    # A negative factor selects the partially saturated law, in which it stands for
    # k_0 / mu (the viscosity is not applied again).
    flow.permeabilityFactor = -clay["intrinsic_permeability_reference"] / clay["water_viscosity"]
    flow.clampKValues = False
    flow.bIntrinsicPerm = clay["permeability_porosity_factor"]
    flow.nUnsatPerm = clay["relative_permeability_exponent"]
    flow.SrM = clay["residual_saturation"]
    flow.SsM = clay["saturated_saturation"]
    flow.Po = clay["retention_pressure_reference"]
    flow.lmbda = clay["retention_exponent_reference"]
    flow.a = clay["retention_pressure_porosity_factor"]
    flow.b = clay["retention_exponent_porosity_factor"]
    flow.constantPorosity = True
    flow.meanInitialPorosity = clay["reference_porosity"]
    # porosity clamps, swelling floor and smallest cell volume as in Appendix .2
    flow.minPoroClamp = 0.1
    flow.maxPoroClamp = 0.8
    flow.betam = clay["swelling_beta"]
    flow.alpham = clay["swelling_alpha"]
    flow.minParticleSwellFactor = 0.5
    flow.freeSwelling = True
    flow.particleSwelling = True
    flow.waterSurfaceTension = clay["surface_tension"]
    flow.permAreaFactor = clay["crack_roughness_factor"]
    # Off: a homogeneous specimen at balance opens no cracks, and our timed steps
    # contain no crack model either.
    flow.crackModelActive = False
    flow.minCellVol = 1e-20
    flow.pZero = -suction
    flow.bndCondIsPressure = [1] * 6
    flow.bndCondValue = [-suction] * 6
    flow.boundaryUseMaxMin = [1] * 6


def equilibrate(settings):
    """Mechanical balance at the initial suction, porosity and saturation frozen."""
    run = settings["run"]
    flow.freezePorosity = True
    flow.freezeSaturation = True
    flow.swelling = False
    unbalanced = float("nan")
    start = time.perf_counter()
    while O.iter < run["max_equilibration_iterations"]:
        O.run(run["equilibration_chunk"], True)
        unbalanced = unbalancedForce()
        if unbalanced <= run["unbalanced_force_threshold"]:
            break
    return {
        "iterations": O.iter,
        "unbalanced_force": unbalanced,
        "wall_time_s": time.perf_counter() - start,
        "n_cells": flow.nCells(),
        "n_contacts": O.interactions.countReal(),
    }


def specimen_box(radii):
    """Lower and upper corners of the sphere centres' box, with the radii or without."""
    corners = [np.inf * np.ones(3), -np.inf * np.ones(3)]
    for body in O.bodies:
        if isinstance(body.shape, Sphere):
            centre = np.array(body.state.pos)
            margin = body.shape.radius if radii else 0.0
            corners[0] = np.minimum(corners[0], centre - margin)
            corners[1] = np.maximum(corners[1], centre + margin)
    return corners


def cell_statistics():
    """Mean, min and max of cell porosity and saturation (checks the homogeneous state)."""
    porosity, saturation = [], []
    for cell in range(flow.nCells()):
        centre = flow.getCellCenter(cell)
        porosity.append(flow.getCellPorosity(centre))
        saturation.append(flow.getCellSaturation(centre))
    return {
        name: {"mean": float(np.mean(v)), "min": float(np.min(v)), "max": float(np.max(v))}
        for name, v in (("porosity", porosity), ("saturation", saturation))
    }


def conductance_statistics():
    """Mean facet conductance between free cells and between an imposed and a free cell.

    Their ratio across saturations shows how the wall facets' conductances follow the
    saturation set on the specimen (those of imposed-pressure cells are not
    interpolated at a remesh). Facets to cells outside the numbering are skipped.
    """
    count = flow.nCells()
    imposed = [bool(flow.getCellPImposed(cell)) for cell in range(count)]
    sums = {"free": [0.0, 0], "imposed_free": [0.0, 0]}
    for cell in range(count):
        for throat, other in enumerate(flow.getNeighbors(cell)):
            if not cell < other < count or (imposed[cell] and imposed[other]):
                continue
            name = "free" if imposed[cell] == imposed[other] else "imposed_free"
            sums[name][0] += flow.getConductivity(cell, throat)
            sums[name][1] += 1
    result = {f"{name}_mean": total / max(n, 1) for name, (total, n) in sums.items()}
    result.update({f"{name}_count": n for name, (_, n) in sums.items()})
    result["imposed_cells"] = int(sum(imposed))
    return result


def set_dynamic(dynamic):
    """Freeze or release every sphere."""
    for body in O.bodies:
        if isinstance(body.shape, Sphere):
            body.dynamic = dynamic
            body.state.vel = Vector3.Zero


def interior_gradient(low, high, fraction=0.4, samples=5):
    """Mean pressure gradient along x between two planes of the inner specimen [Pa/m].

    Pressures are sampled on a grid of the inner half of each plane, at
    x = centre -+ fraction L / 2, so that the boundary cells do not enter.
    """
    centre = 0.5 * (low + high)
    size = high - low
    offsets = (np.arange(samples) / (samples - 1) - 0.5) * 0.5
    planes = []
    for side in (-0.5, 0.5):
        x = centre[0] + side * fraction * size[0]
        planes.append(np.mean([
            flow.getPorePressure((x, centre[1] + u * size[1], centre[2] + w * size[2]))
            for u in offsets for w in offsets
        ]))
    return (planes[1] - planes[0]) / (fraction * size[0])


def permeability_x(settings, suction=None, saturation=None):
    """Water permeability along x from the wall fluxes of a frozen state.

    With ``suction`` None (the equilibrium) the walls get -s_0 -+ dP/2 and the cells
    keep their saturation. Otherwise every cell's saturation is set to ``saturation``
    before the remesh that recomputes the conductances, and the walls get
    -suction -+ dP/2 with dP = ``drop_fraction`` suction; a suction of 0 stands for full
    saturation, measured with the drop of s_0 and wall pressures shifted to dP/2 and
    3 dP/2 (the solve is linear, so the shift does not change k). Yade gives the
    imposed-pressure cells the retention-curve saturation of their own pressure, but
    only after the conductances of the new mesh are computed; those cells are not
    interpolated at a remesh, so the conductances of the facets between them and the
    specimen are computed with the cell default (0.01) instead.
    """
    initial = settings["clay"]["initial_suction"]
    fraction = settings["run"]["drop_fraction"]
    if suction is None:
        drop, mean = fraction * initial, -initial
    elif suction > 0.0:
        drop, mean = fraction * suction, -suction
    else:
        drop = fraction * initial
        mean = drop
    flow.freezePorosity = True
    flow.freezeSaturation = True
    if saturation is not None:
        for cell in range(flow.nCells()):
            flow.setCellSaturation(cell, saturation)
    flow.bndCondIsPressure = [1, 1, 0, 0, 0, 0]
    values = [mean] * 6
    values[flow.xmin] = mean - 0.5 * drop
    values[flow.xmax] = mean + 0.5 * drop
    flow.bndCondValue = values
    flow.updateTriangulation = True
    # The new mesh is used from the second call on; the third is a settled solve.
    for _ in range(3):
        flow.emulateAction()
    inflow = flow.getBoundaryFlux(flow.wallIds[flow.xmin])
    outflow = flow.getBoundaryFlux(flow.wallIds[flow.xmax])
    viscous_rate = flow.viscosity * 0.5 * (abs(inflow) + abs(outflow))
    result = {
        "flux_xmin_m3_s": inflow, "flux_xmax_m3_s": outflow, "pressure_drop_pa": drop,
        "mean_pressure_pa": mean,
    }
    # Two readings of the specimen's extent: the spheres' box (thesis script,
    # utils.aabbExtrema) and the centres' box. The flow boundaries sit on the former
    # (boundaryUseMaxMin), and the flux crosses all of it; the interior gradient below
    # is read at cell duals, not at the sampled points, which biases it by a factor
    # that benchmarks.yade_compare.yade_gradient_factor computes (0.94 to 1.18 here).
    for name, radii in (("sphere_box", True), ("centre_box", False)):
        low, high = specimen_box(radii)
        size = high - low
        area = size[1] * size[2]
        result[name] = {
            "length_m": size[0],
            "area_m2": area,
            "k_x_m2": viscous_rate * size[0] / (area * drop),
        }
    # The same flux over the interior gradient, per centres' box cross-section: the
    # resistance of the imposed-pressure cells left out.
    low, high = specimen_box(False)
    area = result["centre_box"]["area_m2"]
    result["k_x_interior_m2"] = viscous_rate / (area * abs(interior_gradient(low, high)))
    result["cells"] = cell_statistics()
    try:
        result["conductance"] = conductance_statistics()
    except Exception as error:  # a diagnostic only: never lose the run to it
        result["conductance"] = {"error": repr(error)}
    return result


def restore_coupling(settings, saturation):
    """Back to the coupled hydration set-up: all walls at the suction, state live.

    Every cell gets the equilibrium pressure -s and ``saturation`` back, so that the
    saturated permeability state does not leak into the timed run.
    """
    suction = settings["clay"]["initial_suction"]
    for cell in range(flow.nCells()):
        flow.setCellSaturation(cell, saturation)
        flow.setCellPressure(cell, -suction)
    flow.bndCondIsPressure = [1] * 6
    flow.bndCondValue = [-suction] * 6
    flow.freezePorosity = False
    flow.freezeSaturation = False
    flow.resetVolumeSolids = True
    flow.swelling = True
    flow.updateTriangulation = True
    set_dynamic(True)


def engine_times_ns():
    """Accumulated execution time of each engine [ns] (needs O.timingEnabled)."""
    return {type(e).__name__: e.execTime for e in O.engines}


def time_steps(count):
    """Wall time of each of ``count`` single iterations [s].

    ``O.step()`` runs the iteration in this thread; ``O.run(1, True)`` would add the
    ~40 ms polling interval of its wait to every step.
    """
    times = []
    for _ in range(count):
        start = time.perf_counter()
        O.step()
        times.append(time.perf_counter() - start)
    return times


def time_coupled(settings):
    """Median and fastest coupled iteration with a reused factor, and the engine split.

    The fastest iteration estimates the cost on an idle machine, the median includes
    the contention of a shared one (as :mod:`benchmarks.dem` reports its phases).
    """
    run = settings["run"]
    O.run(run["warmup_iterations"], True)  # the remesh of restore_coupling + refactor
    O.timingEnabled = True
    for engine in O.engines:
        engine.execTime = 0
    count = run["coupled_iterations"]
    steps = time_steps(count)
    O.timingEnabled = False
    return {
        "iterations": count,
        "n_contacts": O.interactions.countReal(),
        "per_iteration_s": float(np.median(steps)),
        "per_iteration_min_s": float(np.min(steps)),
        "engines_mean_per_iteration_s": {
            name: 1e-9 * t / count for name, t in engine_times_ns().items()
        },
    }


def time_remesh(settings, iteration_s):
    """Cost of a forced remesh: the steps after the request, minus plain iterations."""
    count = settings["run"]["remesh_steps"]
    flow.updateTriangulation = True
    steps = time_steps(count)
    return {
        "steps_after_request_s": steps,
        "remesh_s": sum(steps) - count * iteration_s,
    }


def main():
    """Build, equilibrate, measure permeability, time, and write the JSON."""
    settings = read_settings()
    n_points = build_scene(settings)
    configure_flow(settings)
    result = {"yade_version": version, "n_points": n_points}
    result["equilibration"] = equilibrate(settings)
    set_dynamic(False)
    result["permeability"] = {
        "equilibrium": permeability_x(settings),
        "saturated": permeability_x(settings, 0.0, settings["clay"]["saturated_saturation"]),
    }
    start = time.perf_counter()
    result["permeability_curve"] = [
        dict(permeability_x(settings, point["suction_pa"], point["saturation"]), **point)
        for point in settings["curve"]
    ]
    result["permeability_curve_wall_time_s"] = time.perf_counter() - start
    positions = [list(b.state.pos) for b in O.bodies if isinstance(b.shape, Sphere)]
    np.savetxt(settings["positions_out"], np.array(positions))
    restore_coupling(
        settings, result["permeability"]["equilibrium"]["cells"]["saturation"]["mean"]
    )
    coupled = time_coupled(settings)
    result["coupled"] = coupled
    result["remesh"] = time_remesh(settings, coupled["per_iteration_s"])
    result["n_cells"] = flow.nCells()
    with open(settings["output_path"], "w") as handle:
        json.dump(result, handle, indent=1)


main()
