"""Hertz-Mindlin contact forces without friction threshold (Caulk 2022, Eqs. 3.2-3.7)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from shared.dem import _kernels
from shared.dem.parameters import DEMParameters
from shared.dem.state import DEMState

__all__ = ["contact_forces", "bond_tension", "bond_stretches"]

FloatArray = npt.NDArray[np.float64]


def contact_forces(
    state: DEMState,
    time_step: float,
    parameters: DEMParameters,
    forces: FloatArray | None = None,
    torques: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Hertz-Mindlin forces and torques of the candidate contacts; updates shear history.

    Parameters
    ----------
    state
        Assembly; ``state.contacts.shear_forces`` is incremented in place.
    time_step
        Time step of the shear displacement increment v_t dt [s].
    parameters
        Young's modulus [Pa] and Poisson ratio [1].
    forces
        (n, 3) array the forces are added to [N]; a new zero array if None.
    torques
        (n, 3) array the torques are added to [N m]; a new zero array if None.

    Returns
    -------
    forces : ndarray, shape (n, 3)
        Total contact force per point [N].
    torques : ndarray, shape (n, 3)
        Total contact torque per point [N m].
    normal_forces : ndarray, shape (n_contacts,)
        Normal force magnitude per candidate contact [N], 0 where the points are apart.

    Notes
    -----
    Normal force (Eq. 3.2): F_n = 4/3 E* sqrt(R*) delta^(3/2), repulsive, with
    E* = E / (2 (1 - nu^2)), R* = r_a r_b / (r_a + r_b) and overlap
    delta = r_a + r_b - |x_b - x_a|. Shear force (Eqs. 3.3-3.7): the stored force is
    turned into the current tangent plane, then incremented by -k_t v_t dt, v_t the
    tangential velocity of the contact point of a relative to b including the spins
    (Eq. 3.6, branch lengths r - delta/2), k_t = 2 sqrt(4 R*) G / (2 - nu) sqrt(delta)
    (Mindlin's tangent stiffness; Eq. 3.3 as printed lacks the sqrt(delta) factor).
    No friction threshold. With the spins, a rigid rotation of a pair leaves its
    contact-point velocities equal, so it creates no shear force.

    Both stiffnesses are evaluated from the current radii at every call, so swelling
    updates them; Yade freezes them at contact creation (docs/yade.md §8,
    defect 11). Separated pairs lose their shear history, as a deleted Yade
    interaction does.

    A bonded pair with a stress-free overlap delta0 (``ContactList.reference_overlaps``,
    see :func:`shared.dem.new_state`) takes its normal force from
    delta - delta0 (r_a + r_b) / (r0_a + r0_b) in place of delta (0 below it): the
    as-built cloud is then the unloaded material, and uniform swelling, which scales
    the cloud and delta0 alike, loads nothing. Its shear stiffness keeps the whole
    overlap, the contact area the points share: a cemented contact resists shear
    before any normal load (a jittered lattice without it is a mechanism).
    """
    n = state.n_points
    forces = _zeros_or_checked(forces, n, "forces")
    torques = _zeros_or_checked(torques, n, "torques")
    if not (np.isfinite(time_step) and time_step > 0.0):
        raise ValueError(f"time_step must be finite and > 0, got {time_step}")
    contacts = state.contacts
    kernel = _kernels.sized(_kernels.hertz_mindlin, _kernels.hertz_mindlin_serial,
                            contacts.pairs.shape[0])
    normal_forces = kernel(
        state.positions, state.velocities, state.spins, state.radii, state.reference_radii,
        contacts.pairs, contacts.reference_overlaps, contacts.shear_forces,
        parameters.effective_modulus, parameters.shear_coefficient, float(time_step),
        forces, torques,
    )
    return forces, torques, normal_forces


def bond_tension(
    state: DEMState, parameters: DEMParameters, forces: FloatArray | None = None
) -> FloatArray:
    """Tension of the intact bonds; breaks those loaded beyond their strength.

    Parameters
    ----------
    state
        Assembly; ``state.bond_broken`` is updated in place.
    parameters
        E* [Pa] (bond stiffness k = E* r_m) and ``bond_tensile_strength`` sigma_t [Pa].
    forces
        (n, 3) array the forces are added to [N]; a new zero array if None.

    Returns
    -------
    ndarray, shape (n, 3)
        ``forces`` with the bond tensions added [N].

    Notes
    -----
    A bond pulled beyond its stress-free overlap delta0 (scaled with the radii) by
    u > 0 pulls back with k u, k = E* r_m, r_m the mean radius of the pair, and breaks
    once k u exceeds sigma_t pi r_m^2; in compression the Hertz contact acts on the
    overlap beyond delta0 (:func:`contact_forces`). Why bonds at all: the thesis's
    points are cohesionless, and a cohesionless quasi-static assembly opens bonds
    wherever the Bishop confinement S s of the compacted state relaxes, with or
    without a porosity field (docs/micro.md, "Initial state and bonds"), which contradicts the thesis's
    Sec. 3.5.5. With sigma_t > 0 only differential loads (a porosity
    field's differences of S s, hydration fronts) break bonds.
    """
    forces = _zeros_or_checked(forces, state.n_points, "forces")
    kernel = _kernels.sized(_kernels.bond_tension, _kernels.bond_tension_serial,
                            state.bonds.shape[0])
    kernel(
        state.positions, state.radii, state.reference_radii, state.bonds, state.bond_overlaps,
        state.bond_broken, parameters.effective_modulus, parameters.bond_tensile_strength,
        forces,
    )
    return forces


def bond_stretches(
    bonds: npt.ArrayLike,
    positions: npt.ArrayLike,
    radii: npt.ArrayLike,
    bond_overlaps: npt.ArrayLike | None = None,
    reference_radii: npt.ArrayLike | None = None,
) -> FloatArray:
    """Stretch u of each bond beyond its stress-free overlap [m]; > 0 means open.

    u = |x_b - x_a| - (r_a + r_b) + delta0 (r_a + r_b) / (r0_a + r0_b): the value
    :func:`bond_tension` loads and breaks bonds by (the same kernel function), and the
    aperture of a crack.

    Parameters
    ----------
    bonds
        (n_bonds, 2) point indices.
    positions
        (n_points, 3) point centres [m].
    radii
        (n_points,) current interaction radii [m].
    bond_overlaps
        (n_bonds,) stress-free overlaps delta0 at the reference radii [m]
        (``DEMState.bond_overlaps``), or None: 0, the stretch is the gap between the
        two spheres.
    reference_radii
        (n_points,) reference radii r0 [m] (``DEMState.reference_radii``); needed with
        ``bond_overlaps``.

    Returns
    -------
    ndarray, shape (n_bonds,)
        Stretch u [m].
    """
    bonds = np.ascontiguousarray(np.asarray(bonds, dtype=np.int64).reshape(-1, 2))
    positions = np.ascontiguousarray(positions, dtype=np.float64)
    radii = np.ascontiguousarray(radii, dtype=np.float64)
    if bond_overlaps is None:
        bond_overlaps, reference_radii = np.zeros(bonds.shape[0]), radii
    elif reference_radii is None:
        raise ValueError("reference_radii are needed with bond_overlaps")
    bond_overlaps = np.ascontiguousarray(bond_overlaps, dtype=np.float64)
    if bond_overlaps.shape != (bonds.shape[0],):
        raise ValueError(f"bond_overlaps must have shape ({bonds.shape[0]},)")
    return _kernels.bond_stretches(
        positions, radii, np.ascontiguousarray(reference_radii, dtype=np.float64), bonds,
        bond_overlaps,
    )


def _zeros_or_checked(array: FloatArray | None, n: int, name: str) -> FloatArray:
    if array is None:
        return np.zeros((n, 3))
    if array.shape != (n, 3):
        raise ValueError(f"{name} must have shape ({n}, 3)")
    return array
