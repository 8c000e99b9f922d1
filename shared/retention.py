"""Van Genuchten water retention with porosity-dependent parameters.

docs/design.md §3 (thesis Eqs. 3.15, 3.26, 3.27):

    S(s) = [1 + (s / zeta)^(1 / (1 - lambda))]^(-lambda),
    zeta(phi) = zeta_0 exp(a (phi_0 - phi)),  lambda(phi) = lambda_0 exp(b (phi_0 - phi)).

Suction s = -p > 0 (p water pressure, gas pressure 0). A non-positive suction gives a
saturated state. :func:`saturation` clamps to [S_r, S_s] (Yade's SrM/SsM); the
derivative :func:`saturation_derivative` is that of the clamped curve (zero where the
clamp is active), so that the explicit update S += dS/dp dp of the flow step and the
storage term of the implicit system stay consistent. :func:`suction` inverts the
unclamped curve. The ``van_genuchten_*`` forms take zeta and lambda and check no range,
for a solver that probes outside the physical one (the macro model's local problems).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from shared.materials import ClayLaws

__all__ = [
    "van_genuchten_saturation",
    "van_genuchten_suction",
    "van_genuchten_suction_slope",
    "van_genuchten_parameters",
    "retention_parameters",
    "saturation",
    "suction",
    "saturation_derivative",
]

FloatArray = npt.NDArray[np.float64]


def van_genuchten_parameters(
    porosity: npt.ArrayLike, material: ClayLaws
) -> tuple[FloatArray, FloatArray]:
    """zeta(phi) [Pa] and lambda(phi) [1] (thesis Eqs. 3.26-3.27, 4.25-4.26), no range
    check: :func:`retention_parameters` checked.

    Parameters
    ----------
    porosity
        Porosity phi [1], any shape.
    material
        Clay parameters (zeta_0 [Pa], lambda_0, a, b, phi_0).
    """
    shift = material.reference_porosity - np.asarray(porosity, dtype=np.float64)
    zeta = material.retention_pressure_reference * np.exp(
        material.retention_pressure_porosity_factor * shift
    )
    exponent = material.retention_exponent_reference * np.exp(
        material.retention_exponent_porosity_factor * shift
    )
    return zeta, exponent


def retention_parameters(
    porosity: npt.ArrayLike, material: ClayLaws
) -> tuple[FloatArray, FloatArray]:
    """Van Genuchten parameters zeta(phi) and lambda(phi) (thesis Eqs. 3.26-3.27).

    Parameters
    ----------
    porosity
        Porosity phi [1], any shape, values in (0, 1).
    material
        Clay parameters (zeta_0 [Pa], lambda_0, a, b, phi_0).

    Returns
    -------
    zeta : ndarray
        Retention pressure [Pa], shape of ``porosity``.
    exponent : ndarray
        Shape exponent lambda [1], shape of ``porosity``.

    Raises
    ------
    ValueError
        If a porosity lies outside (0, 1) or lambda leaves (0, 1).
    """
    porosity = np.asarray(porosity, dtype=np.float64)
    if not np.all((porosity > 0.0) & (porosity < 1.0)):
        raise ValueError("porosity must lie in (0, 1) (NaN not allowed)")
    zeta, exponent = van_genuchten_parameters(porosity, material)
    if np.any(exponent >= 1.0):
        raise ValueError("lambda(porosity) reached 1: retention curve undefined")
    return zeta, exponent


def van_genuchten_saturation(
    suction: npt.ArrayLike, zeta: float | FloatArray, exponent: float | FloatArray
) -> FloatArray:
    """S = [1 + (s / zeta)^(1 / (1 - lambda))]^(-lambda) (Eqs. 3.15, 4.24), unclamped, no
    range check (a solver may probe outside the physical range); s <= 0 gives 1.

    Parameters
    ----------
    suction
        Suction s [Pa].
    zeta, exponent
        Retention pressure zeta [Pa] and exponent lambda [1], broadcastable.
    """
    ratio = np.maximum(np.asarray(suction, dtype=np.float64), 0.0) / zeta
    return (1.0 + ratio ** (1.0 / (1.0 - exponent))) ** (-exponent)


def van_genuchten_suction(
    saturation: npt.ArrayLike, zeta: float | FloatArray, exponent: float | FloatArray
) -> FloatArray:
    """The inverse, s = zeta (S^(-1/lambda) - 1)^(1 - lambda) [Pa], no range check.

    Parameters
    ----------
    saturation
        Water saturation S [1]; 1 gives 0, 0 an infinite suction.
    zeta, exponent
        Retention pressure zeta [Pa] and exponent lambda [1], broadcastable.
    """
    excess = np.maximum(np.asarray(saturation, dtype=np.float64) ** (-1.0 / exponent) - 1.0, 0.0)
    return zeta * excess ** (1.0 - exponent)


def van_genuchten_suction_slope(
    saturation: npt.ArrayLike, zeta: npt.ArrayLike, exponent: npt.ArrayLike
) -> FloatArray:
    """|ds/dS| = zeta (1 - lambda) / lambda (S^(-1/lambda) - 1)^(-lambda) S^(-1/lambda - 1)
    [Pa], the slope of :func:`van_genuchten_suction` at fixed zeta and lambda, no range
    check (S^(-1/lambda) - 1 floored at 1e-300: a finite slope at S = 1).

    Parameters
    ----------
    saturation
        Water saturation S [1].
    zeta, exponent
        Retention pressure zeta [Pa] and exponent lambda [1], broadcastable.
    """
    sat = np.asarray(saturation, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        base = np.maximum(sat ** (-1.0 / exponent) - 1.0, 1e-300)
        return zeta * (1.0 - exponent) / exponent * base ** (-exponent) * sat ** (-1.0 / exponent - 1.0)


def saturation(
    suction: npt.ArrayLike,
    porosity: npt.ArrayLike,
    material: ClayLaws,
) -> FloatArray:
    """Water saturation of the retention curve, clamped to [S_r, S_s].

    Parameters
    ----------
    suction
        Suction s = -p [Pa]; values <= 0 give full saturation (then S_s).
    porosity
        Porosity [1], broadcastable with ``suction``.
    material
        Clay parameters.

    Returns
    -------
    ndarray
        Saturation S_w [1] in [S_r, S_s], broadcast shape.
    """
    suction = np.asarray(suction, dtype=np.float64)
    zeta, exponent = retention_parameters(porosity, material)
    value = van_genuchten_saturation(suction, zeta, exponent)
    return np.clip(value, material.residual_saturation, material.saturated_saturation)


def suction(
    saturation: npt.ArrayLike,
    porosity: npt.ArrayLike,
    material: ClayLaws,
) -> FloatArray:
    """Suction of the (unclamped) retention curve for a given saturation.

    Parameters
    ----------
    saturation
        Water saturation [1] in (0, 1]; 1 gives zero suction.
    porosity
        Porosity [1], broadcastable with ``saturation``.
    material
        Clay parameters.

    Returns
    -------
    ndarray
        Suction s >= 0 [Pa], broadcast shape.

    Raises
    ------
    ValueError
        If a saturation lies outside (0, 1]: zero saturation means infinite suction.
    """
    saturation = np.asarray(saturation, dtype=np.float64)
    if not np.all((saturation > 0.0) & (saturation <= 1.0)):
        raise ValueError("saturation must lie in (0, 1] to be inverted (NaN not allowed)")
    return van_genuchten_suction(saturation, *retention_parameters(porosity, material))


def saturation_derivative(
    suction: npt.ArrayLike,
    porosity: npt.ArrayLike,
    material: ClayLaws,
) -> FloatArray:
    """Closed-form derivative dS_w/dp of the clamped curve w.r.t. water pressure.

    dS/dp = -dS/ds = lambda / (zeta (1 - lambda)) (s/zeta)^(lambda/(1-lambda))
    [1 + (s/zeta)^(1/(1-lambda))]^(-(1+lambda)), zero for s <= 0 and wherever the clamp
    to [S_r, S_s] is active.

    Parameters
    ----------
    suction
        Suction s = -p [Pa].
    porosity
        Porosity [1], broadcastable with ``suction``.
    material
        Clay parameters.

    Returns
    -------
    ndarray
        dS_w/dp >= 0 [1/Pa], broadcast shape.
    """
    suction = np.asarray(suction, dtype=np.float64)
    zeta, exponent = retention_parameters(porosity, material)
    ratio = np.maximum(suction, 0.0) / zeta
    value = (
        exponent
        / (zeta * (1.0 - exponent))
        * ratio ** (exponent / (1.0 - exponent))
        * (1.0 + ratio ** (1.0 / (1.0 - exponent))) ** (-(1.0 + exponent))
    )
    curve = van_genuchten_saturation(suction, zeta, exponent)
    inside = (
        (suction > 0.0)
        & (curve > material.residual_saturation)
        & (curve < material.saturated_saturation)
    )
    return np.where(inside, value, 0.0)
