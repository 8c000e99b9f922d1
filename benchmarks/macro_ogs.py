"""A continuum peer of the macro model: OpenGeoSys on the homogenised column (docs/macro-ogs.md).

``python -m benchmarks run macro_ogs`` (or ``python -m benchmarks.macro_ogs [--ours PATH]``)
runs OpenGeoSys 6.5.9 (the optional extra ``peer`` of pyproject.toml, never needed by the
tests or the default run) twice on the default configuration's container, homogenised at
its global dry density, in an axisymmetric r-z mesh:

- ``RICHARDS_FLOW``: the powder's retention and permeability laws at the homogenised
  porosity, initial suction of the pellets, both plates held at the boundary suction;
- ``RICHARDS_MECHANICS``: the same flow in a rigid container (zero displacement on the
  plates and the curved wall, zero radial displacement on the axis), with OGS's
  ``SaturationDependentSwelling`` stress and an initial stress so that the swelling
  pressure is Eq. 4.33 at the fixed dry density, P = S p'_vc(rho_d) (Eq. 4.31); the wall
  pressures are the normal stresses on the curved wall and the plates.

It then reads our netCDF (``results/macro/weibull.nc`` by default), converts its suction
profiles to saturation with the same retention law, and writes the figure
``results/benchmarks/macro_ogs.png`` and the numbers (hydration times, final wall
pressures, profile differences). The OGS input and output go to a temporary folder.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import meshio
import numpy as np
import numpy.typing as npt

from benchmarks.parameters import CONFIG
from shared.figures import new_figure, save_figure
from shared.permeability import porosity_permeability
from shared.retention import van_genuchten_saturation, van_genuchten_suction

__all__ = ["ColumnSetup", "bench_macro_ogs", "column_setup", "run_ogs"]

OUT = Path("results/benchmarks")
OURS = Path("results/macro/weibull.nc")
FloatArray = npt.NDArray[np.float64]
MPA = 1e-6
DAY = 86400.0
LEVELS = (0.5, 0.9, 0.99)  # mean saturations whose first passage is recorded
PROFILE_DAYS = (1.0, 10.0, 30.0, 100.0, 300.0)  # times of the profiles compared [d]
T0_DAYS = 1e-3  # left edge of the time axes, where the states at t = 0 are marked [d]
# mesh: 1 mm along the axis (the initial front at the plates is sharp), 4 elements across:
# the problem is one-dimensional (no flux through the curved wall, both plates alike), the
# radial direction only carries the wall's stress state
N_R, N_Z = 4, 120
# Young's modulus of the homogenised skeleton [Pa]: with the swelling stress prescribed as
# a stress and zero displacement on the boundary, the stresses do not depend on it; it sets
# the (small) displacements inside, whose rate enters the water balance (RichardsMechanics'
# mean saturation within 0.005 of RichardsFlow's): an assumption, not a thesis parameter
YOUNG_MODULUS = 1.0e9


@dataclass(frozen=True)
class ColumnSetup:
    """The homogenised column, in SI units, with the configuration key of every value."""

    height: float  # [m] macro.cylinder_height_m
    radius: float  # [m] macro.cylinder_radius_m
    dry_density: float  # [kg/m3] macro.mixture.dry_density_kg_m3
    grain_density: float  # [kg/m3] macro.powder.grain_density_kg_m3
    zeta: float  # [Pa] materials.mixture_powder.retention_pressure_reference_pa
    exponent: float  # [1] materials.mixture_powder.retention_exponent_reference
    kr_exponent: float  # [1] materials.mixture_powder.relative_permeability_exponent
    residual_saturation: float  # [1] materials.mixture_powder.residual_saturation
    saturated_saturation: float  # [1] materials.mixture_powder.saturated_saturation
    k0: float  # [m2] materials.mixture_powder.intrinsic_permeability_reference_m2
    b_k: float  # [1] materials.mixture_powder.permeability_porosity_factor
    phi0: float  # [1] materials.mixture_powder.reference_porosity
    water_density: float  # [kg/m3] macro.water_density_kg_m3
    viscosity: float  # [Pa s] macro.water_viscosity_pa_s
    initial_suction: float  # [Pa] materials.mixture_pellet.initial_suction_pa
    boundary_suction: float  # [Pa] macro.boundary_suction_pa
    beta_v: float  # [Pa] macro.powder.swelling_beta_v_pa
    alpha_v: float  # [m3/kg] macro.powder.swelling_alpha_v_m3_per_kg
    poisson_ratio: float  # [1] materials.mixture_pellet.poisson_ratio
    sensors: dict[str, tuple[float, float]]  # name: (height, band width) [m] macro.sensors
    t_end: float  # [s] simulated time, 5 x macro.numerics.max_time_s

    @property
    def porosity(self) -> float:
        """Homogenised porosity 1 - rho_d / rho_s [1]."""
        return 1.0 - self.dry_density / self.grain_density

    @property
    def permeability(self) -> float:
        """Intrinsic permeability at the homogenised porosity (Eq. 4.19) [m2]."""
        return float(porosity_permeability(self.porosity, self.k0, self.b_k, self.phi0))

    @property
    def swelling_pressure(self) -> float:
        """Eq. 4.31 at the global dry density, p'_vc = beta_v exp(alpha_v rho_d) [Pa]."""
        return self.beta_v * math.exp(self.alpha_v * self.dry_density)

    def saturation(self, suction: npt.ArrayLike) -> FloatArray:
        """The retention law S(s) [1] (shared.retention, Eq. 4.24 at phi_0)."""
        return van_genuchten_saturation(suction, self.zeta, self.exponent)

    @property
    def saturation_range(self) -> tuple[float, float]:
        """Saturation at the initial suction and at the plates' suction, the end state [1]."""
        return float(self.saturation(self.initial_suction)), float(self.saturation(self.boundary_suction))

    def equilibrium_fraction(self, saturation: npt.ArrayLike) -> FloatArray:
        """(S - S_0) / (S_eq - S_0) [1]: the share of the way from the initial state to the
        end state held by the plates' suction (S_eq < 1, so S = 0.99 may never come)."""
        s0, s_eq = self.saturation_range
        return (np.asarray(saturation, dtype=np.float64) - s0) / (s_eq - s0)


def column_setup(config: dict = CONFIG) -> ColumnSetup:
    """The homogenised column of a configuration (its first macro case's defaults)."""
    macro, powder = config["macro"], config["materials"]["mixture_powder"]
    pellet = config["materials"]["mixture_pellet"]
    return ColumnSetup(
        height=macro["cylinder_height_m"], radius=macro["cylinder_radius_m"],
        dry_density=macro["mixture"]["dry_density_kg_m3"],
        grain_density=macro["powder"]["grain_density_kg_m3"],
        zeta=powder["retention_pressure_reference_pa"], exponent=powder["retention_exponent_reference"],
        kr_exponent=powder["relative_permeability_exponent"],
        residual_saturation=powder["residual_saturation"], saturated_saturation=powder["saturated_saturation"],
        k0=powder["intrinsic_permeability_reference_m2"], b_k=powder["permeability_porosity_factor"],
        phi0=powder["reference_porosity"],
        water_density=macro["water_density_kg_m3"], viscosity=macro["water_viscosity_pa_s"],
        initial_suction=pellet["initial_suction_pa"], boundary_suction=macro["boundary_suction_pa"],
        beta_v=macro["powder"]["swelling_beta_v_pa"], alpha_v=macro["powder"]["swelling_alpha_v_m3_per_kg"],
        poisson_ratio=pellet["poisson_ratio"],
        sensors={k: (v["height_m"], v.get("band_width_m", 0.012)) for k, v in macro["sensors"].items()},
        t_end=5.0 * macro["numerics"]["max_time_s"],
    )


# --- mesh ------------------------------------------------------------------------------

def _write_meshes(setup: ColumnSetup, folder: Path, quadratic: bool) -> None:
    """The r-z rectangle (x = r, y = z) as ``column.vtu`` and its four sides (``bottom``,
    ``top``, ``wall``, ``axis``) with the ``bulk_node_ids`` OGS maps boundary conditions by."""
    step = 2 if quadratic else 1
    nr, nz = step * N_R + 1, step * N_Z + 1
    i, j = np.meshgrid(np.arange(nr), np.arange(nz), indexing="ij")
    keep = ~((i % 2 == 1) & (j % 2 == 1)) if quadratic else np.ones_like(i, dtype=bool)
    ids = np.full(i.shape, -1, dtype=np.int64)
    ids[keep] = np.arange(int(keep.sum()))
    points = np.column_stack([i[keep] * setup.radius / (nr - 1), j[keep] * setup.height / (nz - 1),
                              np.zeros(int(keep.sum()))])
    cells = []
    for a in range(0, nr - 1, step):
        for b in range(0, nz - 1, step):
            corners = [ids[a, b], ids[a + step, b], ids[a + step, b + step], ids[a, b + step]]
            if quadratic:  # VTK_QUADRATIC_QUAD: corners, then the middles of edges 01, 12, 23, 30
                corners += [ids[a + 1, b], ids[a + 2, b + 1], ids[a + 1, b + 2], ids[a, b + 1]]
            cells.append(corners)
    kind, line = ("quad8", "line3") if quadratic else ("quad", "line")
    meshio.write(folder / "column.vtu", meshio.Mesh(points, [(kind, np.asarray(cells))]))
    sides = {"bottom": ids[:, 0], "top": ids[:, -1], "axis": ids[0, :], "wall": ids[-1, :]}
    for name, nodes in sides.items():
        segments = [[nodes[k], nodes[k + step]] + ([nodes[k + 1]] if quadratic else [])
                    for k in range(0, nodes.size - 1, step)]
        local = {int(n): m for m, n in enumerate(nodes)}
        edges = np.vectorize(local.get)(np.asarray(segments))
        mesh = meshio.Mesh(points[nodes], [(line, edges)],
                           point_data={"bulk_node_ids": nodes.astype(np.uint64)})
        meshio.write(folder / f"{name}.vtu", mesh)


# --- project files ---------------------------------------------------------------------

def _media(setup: ColumnSetup, mechanics: bool) -> str:
    """The MPL medium: retention (SaturationVanGenuchten: m = lambda, entry pressure zeta),
    k_r = S_e^n (RelativePermeabilityGeneralizedPower), constant k and porosity."""
    solid = ("" if not mechanics else
             "<phase><type>Solid</type><properties>"
             "<property><name>density</name><type>Constant</type>"
             f"<value>{setup.grain_density}</value></property>"
             # Delta sigma_sw = -p_vc Delta S (exponents 1 between S = 0 and 1): with the
             # initial stress -S_0 p_vc the swelling stress is -S p_vc, Eq. 4.33
             "<property><name>swelling_stress_rate</name><type>SaturationDependentSwelling</type>"
             f"<swelling_pressures>{setup.swelling_pressure:.9g} {setup.swelling_pressure:.9g} "
             f"{setup.swelling_pressure:.9g}</swelling_pressures><exponents>1 1 1</exponents>"
             "<lower_saturation_limit>0</lower_saturation_limit>"
             "<upper_saturation_limit>1</upper_saturation_limit></property>"
             "</properties></phase>")
    # Biot coefficient 1 (incompressible grains) and Bishop's chi = 0: the pore water acts on
    # the skeleton only through the swelling stress, as in the thesis's Eq. 4.33
    extra = ("<property><name>biot_coefficient</name><type>Constant</type><value>1</value></property>"
             "<property><name>bishops_effective_stress</name><type>Constant</type><value>0</value></property>"
             if mechanics else
             # RichardsFlow's specific storage: rigid grains and water, as the DEM's systems
             "<property><name>storage</name><type>Constant</type><value>0</value></property>")
    return f"""<media><medium>
  <phases>
    <phase><type>AqueousLiquid</type><properties>
      <property><name>viscosity</name><type>Constant</type><value>{setup.viscosity}</value></property>
      <property><name>density</name><type>Constant</type><value>{setup.water_density}</value></property>
    </properties></phase>
    {solid}
  </phases>
  <properties>
    <property><name>reference_temperature</name><type>Constant</type><value>293.15</value></property>
    <property><name>porosity</name><type>Constant</type><value>{setup.porosity:.9g}</value></property>
    <property><name>permeability</name><type>Constant</type><value>{setup.permeability:.9g}</value></property>
    <property><name>saturation</name><type>SaturationVanGenuchten</type>
      <residual_liquid_saturation>{setup.residual_saturation}</residual_liquid_saturation>
      <residual_gas_saturation>{1.0 - setup.saturated_saturation}</residual_gas_saturation>
      <exponent>{setup.exponent}</exponent><p_b>{setup.zeta}</p_b></property>
    <property><name>relative_permeability</name><type>RelativePermeabilityGeneralizedPower</type>
      <residual_liquid_saturation>{setup.residual_saturation}</residual_liquid_saturation>
      <residual_gas_saturation>{1.0 - setup.saturated_saturation}</residual_gas_saturation>
      <min_relative_permeability>0</min_relative_permeability>
      <exponent>{setup.kr_exponent}</exponent></property>
    {extra}
  </properties>
</medium></media>"""


def output_times(setup: ColumnSetup) -> FloatArray:
    """Times written by OGS [s]: geometric from 10 s to the end, and the profile times."""
    times = np.concatenate([np.geomspace(10.0, setup.t_end, 90), np.asarray(PROFILE_DAYS) * DAY])
    return np.unique(np.round(times[times <= setup.t_end], 3))


def _project(setup: ColumnSetup, mechanics: bool) -> str:
    """The whole .prj of one run."""
    dirichlet = ("<boundary_condition><mesh>{mesh}</mesh><type>Dirichlet</type>{component}"
                 "<parameter>{p}</parameter></boundary_condition>")
    pressure_bcs = "".join(dirichlet.format(mesh=m, component="", p="p_plate") for m in ("bottom", "top"))
    if mechanics:
        process = """<process><name>RM</name><type>RICHARDS_MECHANICS</type><integration_order>3</integration_order>
  <constitutive_relation><type>LinearElasticIsotropic</type><youngs_modulus>E</youngs_modulus>
    <poissons_ratio>nu</poissons_ratio></constitutive_relation>
  <process_variables><displacement>displacement</displacement><pressure>pressure</pressure></process_variables>
  <initial_stress>sigma0</initial_stress>
  <secondary_variables><secondary_variable name="sigma"/><secondary_variable name="saturation"/>
    <secondary_variable name="swelling_stress"/></secondary_variables>
  <specific_body_force>0 0</specific_body_force></process>"""
        u_bcs = "".join(dirichlet.format(mesh=m, component=f"<component>{c}</component>", p="zero")
                        for m in ("bottom", "top", "wall") for c in (0, 1))
        u_bcs += dirichlet.format(mesh="axis", component="<component>0</component>", p="zero")
        variables = f"""<process_variable><name>displacement</name><components>2</components><order>2</order>
  <initial_condition>zero2</initial_condition><boundary_conditions>{u_bcs}</boundary_conditions></process_variable>"""
        tolerances = "<abstols>1e-2 1e-13 1e-13</abstols>"
        fields = "".join(f"<variable>{v}</variable>" for v in ("pressure", "saturation", "sigma", "displacement"))
        initial = -setup.saturation(setup.initial_suction) * setup.swelling_pressure
        parameters = f"""<parameter><name>E</name><type>Constant</type><value>{YOUNG_MODULUS}</value></parameter>
  <parameter><name>nu</name><type>Constant</type><value>{setup.poisson_ratio}</value></parameter>
  <parameter><name>zero2</name><type>Constant</type><values>0 0</values></parameter>
  <parameter><name>sigma0</name><type>Constant</type>
    <values>{initial:.9g} {initial:.9g} {initial:.9g} 0</values></parameter>"""
    else:
        process = """<process><name>RF</name><type>RICHARDS_FLOW</type><integration_order>2</integration_order>
  <!-- RICHARDS_FLOW has no analytical Jacobian: Newton on a numerical one, eps 0.01 Pa -->
  <jacobian_assembler><type>CentralDifferences</type><epsilons>1e-2</epsilons></jacobian_assembler>
  <process_variables><process_variable>pressure</process_variable></process_variables>
  <secondary_variables><secondary_variable internal_name="saturation" output_name="saturation"/></secondary_variables>
  <specific_body_force>0 0</specific_body_force><mass_lumping>true</mass_lumping></process>"""
        variables, tolerances = "", "<abstols>1e-2</abstols>"
        fields, parameters = "<variable>pressure</variable><variable>saturation</variable>", ""
    meshes = "".join(f'<mesh axially_symmetric="true">{m}.vtu</mesh>' for m in ("bottom", "top", "wall", "axis"))
    times = " ".join(f"{t:.6g}" for t in output_times(setup))
    name = "RM" if mechanics else "RF"
    return f"""<?xml version="1.0" encoding="ISO-8859-1"?>
<OpenGeoSysProject>
<meshes><mesh axially_symmetric="true">column.vtu</mesh>{meshes}</meshes>
<processes>{process}</processes>
{_media(setup, mechanics)}
<time_loop>
  <processes><process ref="{name}">
    <nonlinear_solver>newton</nonlinear_solver>
    <convergence_criterion><type>PerComponentDeltaX</type><norm_type>INFINITY_N</norm_type>{tolerances}</convergence_criterion>
    <time_discretization><type>BackwardEuler</type></time_discretization>
    <time_stepping><type>IterationNumberBasedTimeStepping</type>
      <t_initial>0</t_initial><t_end>{setup.t_end:.6g}</t_end>
      <initial_dt>1</initial_dt><minimum_dt>1e-3</minimum_dt><maximum_dt>2e5</maximum_dt>
      <number_iterations>2 4 6 8 12 20</number_iterations>
      <multiplier>1.6 1.3 1.1 1.0 0.7 0.4</multiplier></time_stepping>
  </process></processes>
  <output><type>VTK</type><prefix>{name}</prefix>
    <timesteps><pair><repeat>1</repeat><each_steps>100000000</each_steps></pair></timesteps>
    <fixed_output_times>{times}</fixed_output_times>
    <variables>{fields}</variables>
    <suffix>_ts_{{:timestep}}</suffix></output>
</time_loop>
<parameters>
  <parameter><name>p0</name><type>Constant</type><value>{-setup.initial_suction:.9g}</value></parameter>
  <parameter><name>p_plate</name><type>Constant</type><value>{-setup.boundary_suction:.9g}</value></parameter>
  <parameter><name>zero</name><type>Constant</type><value>0</value></parameter>
  {parameters}
</parameters>
<process_variables>
  <process_variable><name>pressure</name><components>1</components><order>1</order>
    <initial_condition>p0</initial_condition><boundary_conditions>{pressure_bcs}</boundary_conditions></process_variable>
  {variables}
</process_variables>
<nonlinear_solvers><nonlinear_solver><name>newton</name><type>Newton</type><max_iter>20</max_iter>
  <linear_solver>direct</linear_solver></nonlinear_solver></nonlinear_solvers>
<linear_solvers><linear_solver><name>direct</name>
  <eigen><solver_type>SparseLU</solver_type><scaling>true</scaling></eigen></linear_solver></linear_solvers>
</OpenGeoSysProject>
"""


# --- running and reading ---------------------------------------------------------------

def _ogs_binary() -> str:
    """The ``ogs`` executable of the ``peer`` extra, beside this interpreter or on PATH."""
    beside = Path(sys.executable).parent / "ogs"
    found = str(beside) if beside.exists() else shutil.which("ogs")
    if found is None:
        raise RuntimeError("OpenGeoSys is not installed: pip install -e '.[peer]' (ogs==6.5.9)")
    return found


def run_ogs(setup: ColumnSetup, folder: Path, mechanics: bool) -> dict:
    """Write the meshes and the project in ``folder``, run OGS, and read its output.

    Returns
    -------
    dict
        ``time`` [s] (output times), ``z`` [m] (nodes on the axis), ``saturation`` (time, z)
        [1] from the nodal pressures through the retention law, ``mean_saturation`` (time)
        [1] over the column; with mechanics ``sensors`` {name: (time,)} the mean radial
        pressure -sigma_rr on the wall over each sensor's band [Pa], ``plates`` (time, 2)
        the area-weighted mean axial pressure -sigma_zz on the upper and lower plates [Pa];
        ``wall_seconds`` [s] the run's wall time.
    """
    folder.mkdir(parents=True, exist_ok=True)
    _write_meshes(setup, folder, quadratic=mechanics)
    (folder / "column.prj").write_text(_project(setup, mechanics))
    start = time.perf_counter()
    done = subprocess.run([_ogs_binary(), "-o", str(folder), str(folder / "column.prj")], cwd=folder,
                          capture_output=True, text=True)
    wall = time.perf_counter() - start
    (folder / "ogs.log").write_text(done.stdout + done.stderr)
    if done.returncode != 0:
        raise RuntimeError(f"ogs failed in {folder}:\n" + "\n".join((done.stdout + done.stderr).splitlines()[-30:]))
    prefix = "RM" if mechanics else "RF"
    entries = ET.parse(folder / f"{prefix}.pvd").getroot().iter("DataSet")
    series = sorted((float(e.get("timestep")), e.get("file")) for e in entries)
    first = meshio.read(folder / series[0][1])
    pts = first.points
    axis = np.flatnonzero(np.isclose(pts[:, 0], 0.0))
    axis = axis[np.argsort(pts[axis, 1])]
    rows = pts[axis, 1] * N_Z / setup.height
    axis = axis[np.isclose(rows, np.round(rows))]  # the corner nodes, where the pressure lives
    wall_nodes = np.flatnonzero(np.isclose(pts[:, 0], setup.radius))
    wall_nodes = wall_nodes[np.argsort(pts[wall_nodes, 1])]
    z, z_wall = pts[axis, 1], pts[wall_nodes, 1]
    times, profiles, sensors, plates = [], [], {k: [] for k in setup.sensors}, []
    for t, name in series:
        mesh = meshio.read(folder / name)
        times.append(t)
        profiles.append(setup.saturation(-mesh.point_data["pressure"].ravel()[axis]))
        if mechanics:
            sigma = mesh.point_data["sigma"]  # components rr, zz, theta theta, rz (tension > 0)
            radial = -sigma[wall_nodes, 0]
            for key, (height, width) in setup.sensors.items():
                band = np.abs(z_wall - height) <= 0.5 * width
                sensors[key].append(float(np.trapezoid(radial[band], z_wall[band]) / np.ptp(z_wall[band])))
            row = []
            for level in (setup.height, 0.0):
                on = np.flatnonzero(np.isclose(pts[:, 1], level))
                on = on[np.argsort(pts[on, 0])]
                r = pts[on, 0]
                row.append(float(np.trapezoid(-sigma[on, 1] * r, r) / np.trapezoid(r, r)))
            plates.append(row)
    saturation = np.asarray(profiles)
    result = {
        "time": np.asarray(times), "z": z, "saturation": saturation,
        "mean_saturation": np.trapezoid(saturation, z, axis=1) / setup.height,
        "wall_seconds": wall,
    }
    if mechanics:
        result["sensors"] = {k: np.asarray(v) for k, v in sensors.items()}
        result["plates"] = np.asarray(plates)
    return result


def first_passage(time_s: FloatArray, values: FloatArray, level: float) -> float:
    """First time [s] ``values`` reaches ``level``, interpolated in log time (linearly from
    a record at t = 0); NaN if never."""
    above = np.flatnonzero(values >= level)
    if above.size == 0:
        return float("nan")
    k = int(above[0])
    if k == 0:
        return float(time_s[0])
    share = (level - values[k - 1]) / (values[k] - values[k - 1])
    if time_s[k - 1] <= 0.0:
        return float(share * time_s[k])
    return float(np.exp(np.log(time_s[k - 1]) + share * np.log(time_s[k] / time_s[k - 1])))


# --- ours ------------------------------------------------------------------------------

def read_ours(path: Path, setup: ColumnSetup) -> dict | None:
    """Our macro output: times [s], saturation profiles from the suction profiles through
    the same retention law, mean saturations of pellets and powder, sensors and plates [Pa].
    None when the file does not exist."""
    if not path.exists():
        return None
    import xarray as xr

    with xr.open_dataset(path) as ds:
        ds = ds.load()
    return {
        "time": ds["time"].values.astype(float),
        "z": ds["z"].values.astype(float),
        "saturation": setup.saturation(ds["suction_profile"].values),
        "mean_saturation": {str(m): ds["mean_saturation"].sel(material=m).values for m in ds["material"].values},
        "sensors": {str(s): ds["sensor_pressure"].sel(sensor=s).values for s in ds["sensor"].values},
        "plates": np.column_stack([ds["axial_pressure_upper"].values, ds["axial_pressure_lower"].values]),
        "passage": {**{str(k): float(v) for k, v in zip(ds["sensor"].values, ds["sensor_passage_time"].values,
                                                        strict=True)},
                    **{f"{k}_plate": float(v) for k, v in zip(ds["plate"].values, ds["axial_passage_time"].values,
                                                             strict=True)}}
        if "sensor_passage_time" in ds else {},
        # our suction at each sensor's height when it passed, linear in time between records
        "passage_suction": {str(k): float(np.interp(float(v), ds["time"].values,
                                                    ds["suction_profile"].sel(z=h, method="nearest").values))
                            for k, v, h in zip(ds["sensor"].values, ds["sensor_passage_time"].values,
                                               ds["sensor_height"].values, strict=True)}
        if "sensor_passage_time" in ds else {},
        "path": str(path),
    }


def _late_mean(time_s: FloatArray, values: FloatArray) -> float:
    """Mean over the last tenth of the elapsed time (our DEM readings fluctuate) [as values]."""
    late = time_s >= 0.9 * time_s[-1]
    return float(np.mean(values[late]))


# --- figure and record -----------------------------------------------------------------

def _on_log_time(ax: object, time_s: FloatArray, values: FloatArray, *style: str, **kwargs: object) -> None:
    """Plot against time [d] on a log axis: the records after t = 0, and the value at
    t = 0 as a marker at the axis's left edge (T0_DAYS)."""
    later = time_s > 0.0
    line = ax.semilogx(time_s[later] / DAY, values[later], *style, **kwargs)[0]
    if not later.all():
        ax.plot([T0_DAYS], [values[~later][0]], "<", color=line.get_color(), ms=5, clip_on=False)


def _figure(setup: ColumnSetup, flow: dict, rm: dict, ours: dict | None, path: Path) -> None:
    fig, axes = new_figure(1, 3, width=4.6, height=3.8)
    ax = axes[0][0]
    colours = [f"C{i}" for i in range(len(PROFILE_DAYS))]
    for day, colour in zip(PROFILE_DAYS, colours, strict=True):
        k = int(np.argmin(np.abs(rm["time"] - day * DAY)))
        ax.plot(rm["z"] * 1e3, rm["saturation"][k], color=colour, label=f"OGS {rm['time'][k] / DAY:.3g} d")
        if ours is not None and ours["time"][-1] >= 0.5 * day * DAY:
            j = int(np.argmin(np.abs(ours["time"] - day * DAY)))
            ax.plot(ours["z"] * 1e3, ours["saturation"][j], "o--", color=colour, ms=3,
                    label=f"ours {ours['time'][j] / DAY:.3g} d")
    ax.set(xlabel="height above the lower plate [mm]", ylabel="saturation [1]",
           title="profiles along the axis (ours: suction via S(s))")
    ax.legend(fontsize=6, ncol=2)
    ax = axes[0][1]
    _on_log_time(ax, flow["time"], flow["mean_saturation"], "k-", lw=2.5, alpha=0.4, label="OGS RichardsFlow")
    _on_log_time(ax, rm["time"], rm["mean_saturation"], "k--", label="OGS RichardsMechanics")
    if ours is not None:
        for material, values in ours["mean_saturation"].items():
            _on_log_time(ax, ours["time"], values, label=f"ours, {material}")
    ax.axhline(setup.saturation_range[1], color="grey", lw=0.8,
               label=f"S at the plates' {setup.boundary_suction * MPA:g} MPa: {setup.saturation_range[1]:.3f}")
    ax.set(xlabel="time [d]", ylabel="mean saturation [1]", title="mean saturation (<: t = 0)", xlim=(T0_DAYS, None))
    ax.legend(fontsize=7)
    ax = axes[0][2]
    for i, (name, values) in enumerate(rm["sensors"].items()):
        _on_log_time(ax, rm["time"], values * MPA, color=f"C{i}", label=f"OGS {name}")
        if ours is not None and name in ours["sensors"]:
            _on_log_time(ax, ours["time"], ours["sensors"][name] * MPA, ":", color=f"C{i}", label=f"ours {name}")
    _on_log_time(ax, rm["time"], rm["plates"][:, 0] * MPA, "k-", lw=2.5, alpha=0.4, label="OGS plates (upper = lower)")
    if ours is not None:
        _on_log_time(ax, ours["time"], ours["plates"][:, 0] * MPA, "k:", label="ours upper plate")
        _on_log_time(ax, ours["time"], ours["plates"][:, 1] * MPA, "k-.", label="ours lower plate")
    ax.axhline(setup.swelling_pressure * MPA, color="r", lw=1,
               label=f"Eq. 4.31 at {setup.dry_density:g} kg/m3: {setup.swelling_pressure * MPA:.2f} MPa")
    ax.axhline(setup.saturation_range[1] * setup.swelling_pressure * MPA, color="r", lw=0.8, ls="--",
               label=f"Eq. 4.33 at S_eq: {setup.saturation_range[1] * setup.swelling_pressure * MPA:.2f} MPa")
    ax.set(xlabel="time [d]", ylabel="wall pressure [MPa]", title="wall pressure (OGS: -sigma_nn; <: t = 0)",
           xlim=(T0_DAYS, None))
    ax.legend(fontsize=6)
    fig.suptitle("Homogenised column, OpenGeoSys 6.5.9, against our DEM mixture" if ours is not None else
                 "Homogenised column, OpenGeoSys 6.5.9 (our netCDF not found)", fontsize=10)
    save_figure(fig, path)


def _profile_differences(rm: dict, ours: dict) -> list[dict]:
    """At each profile time our run reached: RMS and largest |S_ours - S_OGS| along the axis."""
    rows = []
    for day in PROFILE_DAYS:
        if ours["time"][-1] < day * DAY:
            continue
        j = int(np.argmin(np.abs(ours["time"] - day * DAY)))
        k = int(np.argmin(np.abs(rm["time"] - ours["time"][j])))
        finite = np.isfinite(ours["saturation"][j])
        diff = ours["saturation"][j][finite] - np.interp(ours["z"][finite], rm["z"], rm["saturation"][k])
        rows.append({"day_ours": float(ours["time"][j] / DAY), "day_ogs": float(rm["time"][k] / DAY),
                     "rms": float(np.sqrt(np.mean(diff**2))), "max_abs": float(np.max(np.abs(diff))),
                     "mean_ours_minus_ogs": float(np.mean(diff))})
    return rows


def _record(setup: ColumnSetup, flow: dict, rm: dict, ours: dict | None) -> dict:
    def days(t: float) -> float:
        return t / DAY

    levels = {f"{level:g}": level for level in LEVELS}
    record = {
        "ogs_version": "6.5.9",
        "processes": ["RICHARDS_FLOW (quad4)", "RICHARDS_MECHANICS (quad8 u, quad4 p)"],
        "mesh": f"axisymmetric r-z, {N_R} x {N_Z} elements over {setup.radius} m x {setup.height} m",
        "parameters": {
            "porosity": setup.porosity, "permeability_m2": setup.permeability,
            "zeta_pa": setup.zeta, "lambda": setup.exponent, "kr_exponent": setup.kr_exponent,
            "initial_suction_pa": setup.initial_suction, "boundary_suction_pa": setup.boundary_suction,
            "initial_saturation": setup.saturation_range[0],
            "equilibrium_saturation_at_boundary_suction": setup.saturation_range[1],
            "eq_4_33_at_equilibrium_pa": setup.saturation_range[1] * setup.swelling_pressure,
            "eq_4_31_at_global_density_pa": setup.swelling_pressure, "young_modulus_pa": YOUNG_MODULUS,
            "poisson_ratio": setup.poisson_ratio, "t_end_s": setup.t_end,
        },
        "ogs_wall_seconds": {"richards_flow": flow["wall_seconds"], "richards_mechanics": rm["wall_seconds"]},
        "ogs_days_to_mean_saturation": {
            process: {k: days(first_passage(run["time"], run["mean_saturation"], v)) for k, v in levels.items()}
            for process, run in (("richards_flow", flow), ("richards_mechanics", rm))},
        "ogs_days_to_equilibrium_fraction": {
            k: days(first_passage(rm["time"], setup.equilibrium_fraction(rm["mean_saturation"]), v))
            for k, v in levels.items()},
        "ogs_final_mean_saturation": float(rm["mean_saturation"][-1]),
        "ogs_final_day": days(float(rm["time"][-1])),
        "ogs_final_wall_pressure_mpa": {**{k: float(v[-1]) * MPA for k, v in rm["sensors"].items()},
                                        "upper_plate": float(rm["plates"][-1, 0]) * MPA,
                                        "lower_plate": float(rm["plates"][-1, 1]) * MPA},
        "ogs_initial_wall_pressure_mpa": float(np.mean([v[0] for v in rm["sensors"].values()])) * MPA,
        "ogs_rm_vs_rf_max_mean_saturation_difference": float(np.max(np.abs(
            rm["mean_saturation"] - np.interp(rm["time"], flow["time"], flow["mean_saturation"])))),
        "ogs_wall_pressure_at_day_mpa": {
            f"{day:g}": float(np.interp(day * DAY, rm["time"], np.mean(list(rm["sensors"].values()), axis=0))) * MPA
            for day in PROFILE_DAYS},
    }
    from macro.records import PASSAGE_PRESSURE

    # OGS's walls start at Eq. 4.33's S_0 p'_vc, ours at zero: the rise by PASSAGE_PRESSURE
    readings = {**rm["sensors"], "upper_plate": rm["plates"][:, 0], "lower_plate": rm["plates"][:, 1]}
    record["ogs_days_to_rise_by_passage_pressure"] = {
        k: days(first_passage(rm["time"], v - v[0], PASSAGE_PRESSURE)) for k, v in readings.items()}
    record["passage_pressure_pa"] = PASSAGE_PRESSURE
    # a sensor of the continuum rises by PASSAGE_PRESSURE where S passes S_0 + PASSAGE / p'_vc
    rise = setup.saturation_range[0] + PASSAGE_PRESSURE / setup.swelling_pressure
    record["ogs_suction_at_sensor_rise_mpa"] = float(
        van_genuchten_suction(rise, setup.zeta, setup.exponent)) * MPA
    if ours is None:
        record["ours"] = None
        return record
    t = ours["time"]
    record["ours"] = {
        "path": ours["path"],
        "final_day": days(float(t[-1])),
        "days_to_mean_saturation": {m: {k: days(first_passage(t, s, v)) for k, v in levels.items()}
                                    for m, s in ours["mean_saturation"].items()},
        "days_to_equilibrium_fraction": {
            m: {k: days(first_passage(t, setup.equilibrium_fraction(s), v)) for k, v in levels.items()}
            for m, s in ours["mean_saturation"].items()},
        "final_mean_saturation": {m: float(s[-1]) for m, s in ours["mean_saturation"].items()},
        "final_wall_pressure_mpa_last_tenth_mean": {
            **{k: _late_mean(t, v) * MPA for k, v in ours["sensors"].items()},
            "upper_plate": _late_mean(t, ours["plates"][:, 0]) * MPA,
            "lower_plate": _late_mean(t, ours["plates"][:, 1]) * MPA},
        "final_wall_pressure_mpa_last_record": {
            **{k: float(v[-1]) * MPA for k, v in ours["sensors"].items()},
            "upper_plate": float(ours["plates"][-1, 0]) * MPA, "lower_plate": float(ours["plates"][-1, 1]) * MPA},
        "ogs_wall_pressure_at_our_final_day_mpa": float(np.interp(
            t[-1], rm["time"], np.mean(list(rm["sensors"].values()), axis=0))) * MPA,
        "ogs_mean_saturation_at_our_final_day": float(np.interp(t[-1], rm["time"], rm["mean_saturation"])),
        "days_to_passage_pressure": {k: days(v) for k, v in ours["passage"].items()},
        "suction_at_sensor_at_passage_mpa": {k: v * MPA for k, v in ours["passage_suction"].items()},
        "profile_saturation_differences": _profile_differences(rm, ours),
    }
    return record


def bench_macro_ogs(ours: str | Path = OURS, keep: str | Path | None = None) -> dict:
    """OpenGeoSys RichardsFlow and RichardsMechanics on the homogenised column vs our netCDF."""
    setup = column_setup()
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(keep) if keep is not None else Path(scratch)
        flow = run_ogs(setup, folder / "richards_flow", mechanics=False)
        rm = run_ogs(setup, folder / "richards_mechanics", mechanics=True)
    mine = read_ours(Path(ours), setup)
    OUT.mkdir(parents=True, exist_ok=True)
    _figure(setup, flow, rm, mine, OUT / "macro_ogs.png")
    return _record(setup, flow, rm, mine)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.macro_ogs", description=__doc__.splitlines()[0])
    parser.add_argument("--ours", default=str(OURS), help="our macro netCDF (default %(default)s)")
    parser.add_argument("--keep", default=None, help="folder kept with the OGS input and output")
    args = parser.parse_args(argv)
    record = bench_macro_ogs(args.ours, args.keep)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "macro_ogs.json").write_text(json.dumps(record, indent=2))
    print(json.dumps(record, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
