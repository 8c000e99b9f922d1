"""The micro figures read: labelled log ticks, legends off the data, the mean defined."""
from __future__ import annotations

from pathlib import Path

from micro.figures import case_figure, comparison_figure
from micro.run import _dataset
from tests._figures import check_figure, kept_figures  # noqa: F401
from tests.micro.test_run import SUCTIONS, _records


def test_case_figure(tmp_path: Path, kept_figures) -> None:  # noqa: F811
    ds = _dataset(_records(3), SUCTIONS)
    case_figure(ds, "c", tmp_path / "c.png")
    labels = check_figure(kept_figures[-1])
    assert {"permeability [m2]", "boundary suction [Pa]", "saturation [-]"} <= labels


def test_comparison_figure_defines_its_mean(tmp_path: Path, kept_figures) -> None:  # noqa: F811
    cases = {"a": _dataset(_records(3), SUCTIONS), "b": _dataset(_records(3), SUCTIONS * 0.9)}
    comparison_figure(cases, tmp_path / "cmp.png")
    fig = kept_figures[-1]
    labels = check_figure(fig)
    assert {"mean water permeability (m²)", "mean gas permeability (m²)"} <= labels
    assert all("arithmetic mean" in ax.get_title() for ax in fig.get_axes())
    assert len(fig.legends) == 1


def test_convergence_and_scale_figures(tmp_path: Path, kept_figures, rng) -> None:  # noqa: F811
    from micro.figures import convergence_figure, scale_figure
    from micro.studies import convergence_dataset, scale_dataset
    from tests.micro.test_studies import _case, _realization

    cases = {"coarse": _case(rng, 125), "fine": _case(rng, 1000)}
    convergence_figure(convergence_dataset(cases), tmp_path / "conv.png")
    check_figure(kept_figures[-1])
    members = [(_realization(f"e{k}", 0.125), _case(rng, 125)) for k in range(2)]
    scale_figure(scale_dataset(("ref", _case(rng, 125)), 7e-3, members), tmp_path / "scale.png")
    check_figure(kept_figures[-1])


def test_scale_figure_spells_out_its_labels(tmp_path: Path, kept_figures, rng) -> None:  # noqa: F811
    from micro.figures import scale_figure
    from micro.studies import scale_dataset
    from tests.micro.test_studies import _case, _realization

    members = [(_realization(f"e{k}", 0.125), _case(rng, 125)) for k in range(2)]
    members += [(_realization(f"h{k}", 0.01), _case(rng, 27)) for k in range(2)]
    scale_figure(scale_dataset(("ref", _case(rng, 125)), 7e-3, members), tmp_path / "s.png")
    labels = check_figure(kept_figures[-1])
    assert {"mean water permeability (m²)", "standard deviation of saturation (-)"} <= labels
    assert not any(label.startswith(("mu ", "sigma ")) for label in labels)
