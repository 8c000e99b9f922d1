"""State of a DEM point assembly: kinematics, radii, masses, contacts and bonds."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from shared.dem.contacts import bond_pairs, detect_contacts, pair_values
from shared.dem.parameters import DEMParameters

__all__ = ["ContactList", "DEMState", "new_state"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]


@dataclass
class ContactList:
    """Candidate contacts (a Verlet list) with their shear-force history.

    Attributes
    ----------
    pairs
        (n_contacts, 2) point indices, first < second, sorted lexicographically.
    shear_forces
        (n_contacts, 3) shear force on the first point of each pair [N]; the history
        that Eqs. 3.3-3.4 increment.
    detection_positions
        (n_points, 3) positions when the list was built [m].
    detection_radii
        (n_points,) radii when the list was built [m].
    skin
        Verlet margin added to the detection distance [m]; the list stays valid while
        no pair can have closed this margin.
    reference_overlaps
        (n_contacts,) stress-free overlap of each pair at the reference radii [m]:
        the bond's (``DEMState.bond_overlaps``), 0 for unbonded pairs.
    """

    pairs: IntArray
    shear_forces: FloatArray
    detection_positions: FloatArray
    detection_radii: FloatArray
    skin: float
    reference_overlaps: FloatArray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        if self.reference_overlaps.shape != (self.pairs.shape[0],):
            self.reference_overlaps = np.zeros(self.pairs.shape[0])


@dataclass
class DEMState:
    """Mutable state of the point assembly; functions of ``shared.dem`` update it in place.

    Attributes
    ----------
    positions
        (n, 3) point centres [m].
    velocities
        (n, 3) velocities [m/s], at half steps (leapfrog).
    spins
        (n, 3) angular velocities [rad/s], at half steps.
    radii
        (n,) current interaction radii [m] (change with swelling).
    reference_radii
        (n,) radii of the reference state r_0 [m], the base of r = r_0 (1 + eps_v)^(1/3).
    masses
        (n,) point masses [kg], rho 4/3 pi r_0^3, constant.
    inertia
        (n,) moments of inertia [kg m2], 2/5 m r_0^2, constant.
    contacts
        Candidate contact list with shear history.
    bonds
        (n_bonds, 2) point pairs in contact in the reference state, first < second,
        sorted lexicographically; a broken bond that opens is a crack.
    bond_overlaps
        (n_bonds,) stress-free overlap of each bond at the reference radii [m]; zeros
        unless the state was built with ``stress_free_bonds``.
    bond_broken
        (n_bonds,) bonds that broke (:func:`shared.dem.bond_tension`); they carry no
        tension any more.
    fixed
        (n,) points held still by the integrator (e.g. during a permeability test).
    time
        Simulated time [s].
    """

    positions: FloatArray
    velocities: FloatArray
    spins: FloatArray
    radii: FloatArray
    reference_radii: FloatArray
    masses: FloatArray
    inertia: FloatArray
    contacts: ContactList
    bonds: IntArray
    bond_overlaps: FloatArray = field(default_factory=lambda: np.zeros(0))
    bond_broken: BoolArray = field(default_factory=lambda: np.zeros(0, dtype=np.bool_))
    fixed: BoolArray = field(default_factory=lambda: np.zeros(0, dtype=np.bool_))
    time: float = 0.0

    def __post_init__(self) -> None:
        n = self.positions.shape[0]
        for name in ("positions", "velocities", "spins"):
            if getattr(self, name).shape != (n, 3):
                raise ValueError(f"{name} must have shape ({n}, 3)")
        for name in ("radii", "reference_radii", "masses", "inertia"):
            if getattr(self, name).shape != (n,):
                raise ValueError(f"{name} must have shape ({n},)")
        if self.fixed.shape != (n,):
            self.fixed = np.zeros(n, dtype=np.bool_)
        n_bonds = self.bonds.shape[0]
        if self.bond_overlaps.shape != (n_bonds,):
            self.bond_overlaps = np.zeros(n_bonds)
        if self.bond_broken.shape != (n_bonds,):
            self.bond_broken = np.zeros(n_bonds, dtype=np.bool_)

    @property
    def n_points(self) -> int:
        """Number of points."""
        return int(self.positions.shape[0])


def new_state(
    positions: npt.ArrayLike,
    radii: npt.ArrayLike,
    parameters: DEMParameters,
    skin_fraction: float = 0.1,
    bond_tolerance: float = 1e-9,
    stress_free_bonds: bool = False,
) -> DEMState:
    """Assemble a state at rest, detect its contacts and take them as its bonds.

    Parameters
    ----------
    positions
        (n, 3) point centres [m].
    radii
        (n,) interaction radii [m]; also the reference radii r_0.
    parameters
        Density [kg/m3] (masses) and interaction radius factor [1] (detection).
    skin_fraction
        Verlet margin as a fraction of the mean radius [1].
    bond_tolerance
        Pairs up to (1 + bond_tolerance)(r_a + r_b) apart are bonded [1]; raise it to
        the grid jitter to bond every neighbour of a jittered grid, or re-bond with
        :func:`shared.dem.bond_pairs` once the specimen is in equilibrium.
    stress_free_bonds
        Take the given cloud as the unloaded material: each bond's overlap becomes its
        stress-free overlap (``bond_overlaps``), so the state starts without the
        self-stress that the overlaps of a jittered grid would otherwise store.

    Returns
    -------
    DEMState
        At rest, masses rho 4/3 pi r^3 and moments of inertia 2/5 m r^2 (solid
        spheres), bonds = pairs touching or overlapping (within the tolerance).
    """
    positions = np.ascontiguousarray(positions, dtype=np.float64)
    radii = np.ascontiguousarray(radii, dtype=np.float64)
    skin = float(skin_fraction * radii.mean())
    pairs = detect_contacts(positions, radii, parameters.interaction_radius_factor, skin)
    contacts = ContactList(
        pairs=pairs,
        shear_forces=np.zeros((pairs.shape[0], 3)),
        detection_positions=positions.copy(),
        detection_radii=radii.copy(),
        skin=skin,
    )
    bonds = bond_pairs(positions, radii, bond_tolerance)
    overlaps = np.zeros(bonds.shape[0])
    if stress_free_bonds:
        gaps = np.linalg.norm(positions[bonds[:, 1]] - positions[bonds[:, 0]], axis=1)
        overlaps = np.maximum(radii[bonds].sum(axis=1) - gaps, 0.0)
    contacts.reference_overlaps = pair_values(pairs, bonds, overlaps)
    masses = parameters.density * 4.0 / 3.0 * np.pi * radii**3
    return DEMState(
        positions=positions.copy(),
        velocities=np.zeros_like(positions),
        spins=np.zeros_like(positions),
        radii=radii.copy(),
        reference_radii=radii.copy(),
        masses=masses,
        inertia=0.4 * masses * radii**2,
        contacts=contacts,
        bonds=bonds,
        bond_overlaps=overlaps,
    )
