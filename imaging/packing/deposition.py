"""Sequential deposition of flat elliptic disks (Ferrage et al. 2015, Sec. II).

Particles enter one at a time at the top of a square box of width w, periodic in x and
y, with a rigid floor at z = 0, fall vertically until their lowest gap reaches d_cont/2,
then try ``n_cycles`` x ``attempts_per_cycle`` random moves (slide, swivel about the
contact point, in-plane rotation), each accepted only if the barycentre descends and no
overlap appears; amplitudes are halved between cycles. Particles in the bed never move.
Contacts are exact on the convex shape by default (GJK, :mod:`._contact_kernels`), or
the paper's multiscale scan with ``scan_points`` > 0 (:mod:`._scan_kernels`). Our
readings of Sec. II.A and the options: docs/packing.md, "imaging.packing.deposition".

References: E. Ferrage et al., Phys. Rev. E 91, 062210 (2015),
doi:10.1103/PhysRevE.91.062210; D. Coelho, J.-F. Thovert and P. M. Adler, Phys. Rev.
E 55, 1959 (1997).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from imaging.packing import _contact_kernels, _grid_kernels, _settle_kernels
from imaging.packing._bed import BedIndex
from imaging.packing.orientation import euler_angles, fold_upward, normals, rotation_matrices
from imaging.packing.population import volumes
from shared.progress import Progress

__all__ = ["DepositionParameters", "Packing", "deposit"]

log = logging.getLogger("imaging.packing")


@dataclass(frozen=True)
class DepositionParameters:
    """Algorithm parameters (Table II and III of the paper).

    Attributes
    ----------
    box_width : float
        Width w of the square box [m].
    contact_distance : float
        d_cont: a gap below it is a contact; falls stop at d_cont / 2 [m].
    theta_max : float
        Initial tilt of the normal from z [rad], in [0, pi/2].
    theta_random : bool
        True: theta_ini uniform in (0, theta_max); False: theta_ini = theta_max.
    slide_amplitude : float
        A_slide, largest slide [m].
    swivel_amplitude : float
        A_swiv, largest swivel about the contact point [rad].
    rotation_amplitude : float
        A_rot, largest in-plane rotation [rad] (only used for l_a > l_b).
    n_cycles : int
        Cycles of move attempts.
    attempts_per_cycle : int
        Move attempts per cycle.
    amplitude_reduction : float
        Factor applied to the amplitudes after each cycle.
    steepest_slide : bool
        True: slides go horizontally away from the pivot; False: in a random horizontal
        direction.
    steepest_swivel : bool
        True: swivels turn about the horizontal axis of steepest descent of the
        barycentre; False: about a random horizontal axis. Either way a move is accepted
        only if the barycentre descends.
    contact_line_swivel : bool
        True: with two contacts a swivel turns about the line through them (the
        barycentre circling the foot of the altitude); False: about the horizontal axis
        of ``steepest_swivel`` through that foot.
    log_interval : float
        Seconds between progress log lines [s].
    scan_points : int
        n_sp of the contact scan (Sec. II B, :mod:`._scan_kernels`); 0: exact contacts.
    """

    box_width: float
    contact_distance: float
    theta_max: float
    theta_random: bool
    slide_amplitude: float
    swivel_amplitude: float
    rotation_amplitude: float
    n_cycles: int = 3
    attempts_per_cycle: int = 800
    amplitude_reduction: float = 0.5
    steepest_slide: bool = True
    steepest_swivel: bool = True
    contact_line_swivel: bool = True
    log_interval: float = 30.0
    scan_points: int = 0


@dataclass
class Packing:
    """A deposited bed.

    Attributes
    ----------
    centers : ndarray, shape (n, 3)
        Barycentres [m], x and y in [0, w).
    rotations : ndarray, shape (n, 3, 3)
        Columns: l_a axis, l_b axis and upward normal in the box frame.
    semi_axes : ndarray, shape (n, 3)
        (l_a, l_b, h / 2) [m].
    box_width : float
        w [m].
    contact_distance : float
        d_cont [m].
    accepted_moves : ndarray, shape (n,)
        Accepted moves per particle.
    wall_time : ndarray, shape (n,)
        Wall time spent settling each particle [s].
    """

    centers: npt.NDArray[np.float64]
    rotations: npt.NDArray[np.float64]
    semi_axes: npt.NDArray[np.float64]
    box_width: float
    contact_distance: float
    accepted_moves: npt.NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    wall_time: npt.NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))

    @property
    def euler(self) -> npt.NDArray[np.float64]:
        """ZZZ Euler angles (phi, theta, psi) [rad], theta in [0, pi/2]."""
        return euler_angles(self.rotations)

    @property
    def normals(self) -> npt.NDArray[np.float64]:
        """Upward unit normals."""
        return normals(self.rotations)

    @property
    def volumes(self) -> npt.NDArray[np.float64]:
        """Particle volumes [m^3]."""
        return volumes(self.semi_axes)


def _entry_pose(
    axes: npt.NDArray[np.float64],
    params: DepositionParameters,
    bed: BedIndex,
    rng: np.random.Generator,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    x, y, phi, psi, u = rng.random(5)
    theta = params.theta_max * (u if params.theta_random else 1.0)
    rot = rotation_matrices([[2.0 * np.pi * phi, theta, 2.0 * np.pi * psi]])[0]
    center = np.array([x * params.box_width, y * params.box_width, 0.0])
    ext = np.empty(3)
    _contact_kernels.half_extents(rot, axes, ext)
    floor = _grid_kernels.entry_altitude(center, ext, bed.heights, bed.fine.cell_xy)
    center[2] = floor + ext[2] + params.contact_distance
    return center, rot


def deposit(
    semi_axes: npt.NDArray[np.float64],
    params: DepositionParameters,
    rng: np.random.Generator,
) -> Packing:
    """Build a bed by sequential deposition, in the order of ``semi_axes``.

    Parameters
    ----------
    semi_axes : ndarray, shape (n, 3)
        (l_a, l_b, h / 2) [m] of the particles, in order of arrival.
    params : DepositionParameters
    rng : numpy.random.Generator
        Draws entry positions, orientations and moves; the bed depends only on its state.

    Returns
    -------
    Packing
    """
    semi_axes = np.ascontiguousarray(semi_axes, dtype=np.float64)
    n = semi_axes.shape[0]
    bed = BedIndex(semi_axes, params.box_width, params.contact_distance, params.scan_points)
    geometry = bed.geometry
    amplitudes = np.array(
        [params.slide_amplitude, params.swivel_amplitude, params.rotation_amplitude])
    n_attempts = params.n_cycles * params.attempts_per_cycle
    steepest = np.array([params.steepest_slide, params.steepest_swivel, params.contact_line_swivel])
    accepted = np.zeros(n, dtype=np.int64)
    wall = np.zeros(n)
    progress = Progress(n, "placed particles", log, interval=params.log_interval)
    for i in range(n):
        t0 = time.perf_counter()
        axes = semi_axes[i]
        center, rot = _entry_pose(axes, params, bed, rng)
        uniforms = rng.random((n_attempts, 4))
        elliptic = axes[0] > axes[1] * (1.0 + 1e-12) and params.rotation_amplitude > 0.0
        accepted[i] = _settle_kernels.settle(
            center, rot, axes, uniforms, amplitudes, params.amplitude_reduction,
            params.n_cycles, 3 if elliptic else 2, steepest, bed.centers,
            bed.rotations, bed.axes, bed.extents, bed.fine.head, bed.coarse.head, bed.link,
            geometry, bed.found, bed.shifts, bed.drops, bed.witness)
        bed.add(i, center, rot)
        now = time.perf_counter()
        wall[i] = now - t0
        progress.update(i + 1, force=i == n - 1)
    return Packing(
        centers=bed.centers.copy(),
        rotations=fold_upward(bed.rotations),
        semi_axes=semi_axes.copy(),
        box_width=params.box_width,
        contact_distance=params.contact_distance,
        accepted_moves=accepted,
        wall_time=wall,
    )
