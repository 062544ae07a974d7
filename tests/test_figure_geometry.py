"""Every figure kinid draws, checked at the size a report shows it: no legend over plotted data, no text below
8 pt where it is read (tests/figure_geometry.py, an independent consumer).

Every command that draws is run as a user would (each report, each ``--plot``), with kinid.reports.figures.save_figure
watched: each figure is checked as it is saved.
"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

from figure_geometry import problems
from kinid.cli import main
from kinid.urdf import path as urdf_path

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
STAGES = EXAMPLES / "stages"
MACHINE = str(urdf_path("five_axis_bc"))
PIXEL_TO_MM = ["0.0049931", "0.0002617", "0.0002617", "-0.0049931"]


def _commands(d: Path) -> list:
    """Every command that draws, with its outputs in ``d``."""
    backlash = ["backlash", "--data", str(STAGES / "backlash" / "log.csv"), "--travel-mm", "0.4"]
    uvw = ["uvw", "--data", str(STAGES / "uvw_moves.csv"), "--lead-um", "2000"]
    dual = ["dual-axis", "--data", str(STAGES / "dual_axis.csv"), "--pixel-to-mm", *PIXEL_TO_MM]
    contour = ["contour", "--simulate", "--sim-frames", "40", "--workers", "1"]
    return [
        ["demo", "--out", str(d / "demo")],  # the selection report: steps, before and after
        ["identify", "--machine", MACHINE, "--data", str(d / "obs.csv"), "--add", "EXX:periodic:10", "EYY:poly3",
         "--out", str(d / "fit.json"), "--report", str(d / "identify")],
        ["diagnose", "--fit", str(d / "fit.json"), "--data", str(d / "obs.csv"), "--report", str(d / "diagnose")],
        ["verify", "--fit", str(d / "fit.json"), "--data", str(d / "obs.csv"), "--before", str(d / "obs.csv"),
         "--report", str(d / "verify")],
        [*backlash, "--report", str(d / "backlash"), "--plot", str(d / "backlash.png")],
        [*uvw, "--report", str(d / "uvw"), "--plot", str(d / "uvw.png")],
        ["uvw", "--simulate", "--plot", str(d / "uvw_sim.png")],
        [*dual, "--report", str(d / "dual"), "--plot", str(d / "dual.png")],
        ["dual-axis", "--simulate", "--plot", str(d / "dual_sim.png")],
        [*contour, "--report", str(d / "contour"), "--plot", str(d / "contour.png")],
        ["iso230-2", "--data", str(EXAMPLES / "x_runs.csv"), "--axis", "X", "--plot", str(d / "iso.png"), "--report",
         str(d / "iso")],
    ]


@pytest.fixture(scope="module")
def checked(tmp_path_factory):
    """figure name -> its problems, for every figure the commands save."""
    import kinid.reports.figures

    d = tmp_path_factory.mktemp("figures")
    assert main(["simulate", "--machine", MACHINE, "--errors", str(EXAMPLES / "errors.json"), "--noise-um", "1",
                 "--seed", "4", "--out", str(d / "obs.csv")]) == 0
    found = {}
    real = kinid.reports.figures.save_figure

    def save(fig, path, *, dpi=110, tight=True):
        name = f"{Path(path).parent.name.split('.kinid-new-')[0].lstrip('.')}/{Path(path).name}"
        found[name] = problems(fig, dpi, tight)
        return real(fig, path, dpi=dpi, tight=tight)

    with pytest.MonkeyPatch.context() as patch:
        # kinid.reports.figures, and every module that took save_figure from it by name before this test ran
        for module in [m for m in list(sys.modules.values()) if getattr(m, "save_figure", None) is real]:
            patch.setattr(module, "save_figure", save)
        for argv in _commands(d):
            assert main(argv) == 0, argv
    return found


def test_every_figure_is_readable_where_it_is_shown(checked):
    assert len(checked) >= 25, sorted(checked)
    bad = {name: p for name, p in checked.items() if p}
    assert not bad, "\n".join(f"{name}: {'; '.join(p[:3])}" for name, p in sorted(bad.items()))


def test_the_check_sees_a_legend_over_data_and_small_text():
    """The check can fail: a legend dropped on the data, and 8 pt text in a figure shown at half its width."""
    from kinid.reports.figures import new_figure

    fig = new_figure((6, 3))
    ax = fig.subplots()
    ax.plot(range(50), [1.0] * 50, "o", label="data")
    ax.legend(loc="center left")
    found = problems(fig)
    assert any("covers" in p for p in found), found
    wide = new_figure((20, 3))
    ax = wide.subplots()
    ax.plot([0, 1], [0, 1])
    ax.set_title("small", fontsize=8)
    assert any("'small'" in p for p in problems(wide))
    crowded = new_figure((4, 3))
    left, right = crowded.subplots(1, 2)
    left.set_title("a title long enough to reach the next panel")
    right.set_title("next")
    assert any("runs into" in p for p in problems(crowded))
