"""Orientation of elliptic disks: ZZZ Euler angles, rotation matrices and normals.

The paper's "ZZZ convention" is read as proper Euler angles about z, the line of nodes
x' and the new z'' (Goldstein's x-convention): R = Rz(phi) Rx(theta) Rz(psi). The
columns of R are the particle axes (l_a, l_b, normal) in the box frame, so theta is the
angle between the particle normal and the z axis of the box. A disk is unchanged by a
half turn about its l_a axis, which maps the normal n to -n; using it, every
orientation is written with theta in [0, pi/2].
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

__all__ = ["rotation_matrices", "euler_angles", "normals", "fold_upward"]


def rotation_matrices(euler: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Rotation matrices from ZZZ Euler angles.

    Parameters
    ----------
    euler : array_like, shape (n, 3)
        (phi, theta, psi) [rad].

    Returns
    -------
    ndarray, shape (n, 3, 3)
        R = Rz(phi) Rx(theta) Rz(psi); columns are the particle axes in the box frame.
    """
    angles = np.atleast_2d(np.asarray(euler, dtype=np.float64))
    cf, sf = np.cos(angles[:, 0]), np.sin(angles[:, 0])
    ct, st = np.cos(angles[:, 1]), np.sin(angles[:, 1])
    cp, sp = np.cos(angles[:, 2]), np.sin(angles[:, 2])
    rot = np.empty((angles.shape[0], 3, 3))
    rot[:, 0, 0] = cf * cp - sf * ct * sp
    rot[:, 0, 1] = -cf * sp - sf * ct * cp
    rot[:, 0, 2] = sf * st
    rot[:, 1, 0] = sf * cp + cf * ct * sp
    rot[:, 1, 1] = -sf * sp + cf * ct * cp
    rot[:, 1, 2] = -cf * st
    rot[:, 2, 0] = st * sp
    rot[:, 2, 1] = st * cp
    rot[:, 2, 2] = ct
    return rot


def fold_upward(rot: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Same disks, with every normal pointing upward (half turn about l_a where needed).

    Parameters
    ----------
    rot : ndarray, shape (n, 3, 3)

    Returns
    -------
    ndarray, shape (n, 3, 3)
    """
    out = np.array(rot, dtype=np.float64, copy=True)
    down = out[:, 2, 2] < 0.0
    out[down, :, 1:] *= -1.0
    return out


def euler_angles(rot: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """ZZZ Euler angles of rotation matrices, with theta in [0, pi/2].

    Parameters
    ----------
    rot : ndarray, shape (n, 3, 3)

    Returns
    -------
    ndarray, shape (n, 3)
        (phi, theta, psi) [rad], phi and psi in [0, 2 pi). When theta is 0 the split
        between phi and psi is arbitrary: phi = 0 is returned.
    """
    r = fold_upward(rot)
    theta = np.arccos(np.clip(r[:, 2, 2], -1.0, 1.0))
    sin_theta = np.sin(theta)
    tilted = sin_theta > 1e-12
    phi = np.where(tilted, np.arctan2(r[:, 0, 2], -r[:, 1, 2]), 0.0)
    psi = np.where(tilted, np.arctan2(r[:, 2, 0], r[:, 2, 1]), np.arctan2(r[:, 1, 0], r[:, 0, 0]))
    two_pi = 2.0 * np.pi
    return np.stack([np.mod(phi, two_pi), theta, np.mod(psi, two_pi)], axis=1)


def normals(rot: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Unit normals of the basal surfaces, pointing upward.

    Parameters
    ----------
    rot : ndarray, shape (n, 3, 3)

    Returns
    -------
    ndarray, shape (n, 3)
    """
    return fold_upward(rot)[:, :, 2]
