"""The micro figures read: labelled log ticks, legends off the data, the mean defined."""
from __future__ import annotations

from pathlib import Path

from micro.figures import case_figure, comparison_figure
from micro.results import records_dataset
from tests._figures import check_figure, kept_figures  # noqa: F401
from tests.micro.test_run import SUCTIONS, _records


def test_case_figure(tmp_path: Path, kept_figures) -> None:  # noqa: F811
    ds = records_dataset(_records(3), SUCTIONS)
    case_figure(ds, "c", tmp_path / "c.png")
    labels = check_figure(kept_figures[-1])
    assert {"permeability [m2]", "boundary suction [Pa]", "saturation [-]"} <= labels


def test_comparison_figure_defines_its_mean(tmp_path: Path, kept_figures) -> None:  # noqa: F811
    cases = {"a": records_dataset(_records(3), SUCTIONS), "b": records_dataset(_records(3), SUCTIONS * 0.9)}
    comparison_figure(cases, tmp_path / "cmp.png")
    fig = kept_figures[-1]
    labels = check_figure(fig)
    assert {"mean water permeability [m2]", "mean gas permeability [m2]"} <= labels
    assert all("arithmetic mean" in ax.get_title() for ax in fig.get_axes())
    assert fig._suptitle.get_text() == "micro cases a, b"
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
    assert {"mean\nwater permeability [m2]", "std. dev. of\nsaturation [-]"} <= labels
    assert not any(label.startswith(("mu ", "sigma ")) for label in labels)


def test_case_figure_names_the_case_counts_cracks_on_integers_and_hides_an_empty_panel(
        tmp_path: Path, kept_figures) -> None:  # noqa: F811
    ds = records_dataset(_records(3), SUCTIONS)
    case_figure(ds, "het", tmp_path / "het.png")
    fig = kept_figures[-1]
    check_figure(fig)  # integer ticks on "number of cracks", one legend entry per line
    assert fig._suptitle.get_text().startswith("micro case het")
    texts = [t.get_text() for ax in fig.get_axes() if ax.get_legend() for t in ax.get_legend().get_texts()]
    assert "number of cracks (right axis)" in texts
    colorbars = [ax for ax in fig.get_axes() if getattr(ax, "_colorbar", None) is not None]
    assert [ax.get_ylabel() for ax in colorbars] == ["saturation [-]"]
    # no crack at any checkpoint: the crack panel says so instead of empty axes
    case_figure(ds.assign(crack_count=ds["crack_count"] * 0), "hom", tmp_path / "hom.png")
    fig = kept_figures[-1]
    check_figure(fig)
    off = [ax for ax in fig.get_axes() if not ax.axison]
    assert len(off) == 1 and off[0].texts[0].get_text() == "no crack opened in this case"
