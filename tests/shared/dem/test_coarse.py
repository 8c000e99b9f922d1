"""The rigid correction of a static solve against closed-form translations."""

import numpy as np
import pytest

from shared.dem import rigid_translation


def test_linear_springs_are_balanced_in_one_step():
    """Points on anisotropic linear springs: R(t) = R0 - K t with K the sum of the springs'
    stiffness matrices, so the translation is K^-1 R0 and the first full step is taken."""
    rng = np.random.default_rng(3)
    n = 50
    factors = rng.normal(size=(n, 3, 3))
    stiffness = factors @ factors.transpose(0, 2, 1) + 3.0 * np.eye(3)  # (n, 3, 3) SPD [N/m]
    offsets = rng.normal(scale=1e-3, size=(n, 3))  # positions minus anchors [m]

    def resultant_at(shift):
        resultant = -np.einsum("nij,nj->i", stiffness, offsets + shift)
        return resultant, float(np.linalg.norm(resultant))

    start, ratio = resultant_at(np.zeros(3))
    shift, evaluations = rigid_translation(resultant_at, start, ratio, 1e-6)
    expected = np.linalg.solve(stiffness.sum(axis=0), start)
    assert shift == pytest.approx(expected, rel=1e-6, abs=1e-12)
    assert evaluations == 4
    assert resultant_at(shift)[1] < 1e-6 * ratio


def test_hertz_pellet_between_plates_converges_to_the_midplane():
    """A sphere of radius r between plates 2 (r - d) apart, off-centre by c: each plate pushes
    k delta^(3/2). Repeated corrections bring it to the midplane, c = 0, where the two
    overlaps are both d, and each step lowers the imbalance."""
    d, k = 2e-5, 1e9  # overlap at the midplane [m], Hertz constant [N m^-1.5]

    def resultant_at(shift, centre):
        z = centre + shift[2]
        lower, upper = max(d - z, 0.0) ** 1.5, max(d + z, 0.0) ** 1.5
        resultant = np.array([0.0, 0.0, k * (lower - upper)])
        return resultant, abs(resultant[2]) / (0.5 * k * (lower + upper))

    centre, ratios = 1.5e-5, []
    for _ in range(4):

        def planar(shift, at=centre):
            # only z is free: the x and y rows add a unit stiffness so the tangent is regular
            resultant, value = resultant_at(shift, at)
            return resultant - np.array([shift[0], shift[1], 0.0]), value

        start, ratio = planar(np.zeros(3))
        ratios.append(ratio)
        shift, _ = rigid_translation(planar, start, ratio, 1e-6 * d)
        assert shift is not None
        centre += shift[2]
    assert np.all(np.diff(ratios) < 0.0)
    assert centre == pytest.approx(0.0, abs=1e-6 * d)


def test_no_stiffness_gives_no_step():
    """A resultant that does not depend on the translation has a singular tangent."""
    resultant = np.array([1.0, 0.0, 0.0])
    shift, evaluations = rigid_translation(lambda shift: (resultant, 1.0), resultant, 1.0, 1e-6)
    assert shift is None
    assert evaluations == 3


def test_a_refused_shift_is_halved_until_it_is_allowed():
    """Linear springs whose ratio is infinite beyond a third of the Newton step (as the
    macro relaxation refuses a shift that inverts a cell): the step is halved twice, to a
    quarter of K^-1 R0, which lowers the ratio by 1 - 1/4."""
    stiffness = np.diag([2.0, 3.0, 5.0])  # [N/m]
    offset = np.array([1e-3, -2e-3, 5e-4])  # [m]
    newton = -offset

    def resultant_at(shift):
        resultant = -stiffness @ (offset + shift)
        inverted = np.linalg.norm(shift) > np.linalg.norm(newton) / 3.0
        return resultant, np.inf if inverted else float(np.linalg.norm(resultant))

    start, ratio = resultant_at(np.zeros(3))
    shift, evaluations = rigid_translation(resultant_at, start, ratio, 1e-9)
    assert shift == pytest.approx(0.25 * newton, rel=1e-6)
    assert evaluations == 3 + 3
    assert resultant_at(shift)[1] == pytest.approx(0.75 * ratio, rel=1e-6)
