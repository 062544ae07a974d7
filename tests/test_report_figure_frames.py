"""A report's figures drawn again in the frame of the one before (kinid.reports.figures.FigureFrames) are the pixels
of the same figures drawn new: each kind of residual figure a report draws for its first and last fit, drawn for one
set of residuals and then for another of a different size (the residuals against the axes and binned, in each
other's frame too), with directions of approach, a periodogram panel of an
axis not moved and held parameters beside the singular values only the first time."""
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

from kinid.identification.reporting import figures as plots
from kinid.reports.figures import FigureFrames

MACHINE = SimpleNamespace(axes=[SimpleNamespace(name=n, kind=k) for n, k in
                                (("X", "prismatic"), ("Y", "prismatic"), ("Z", "prismatic"), ("B", "revolute"),
                                 ("C", "revolute"))])


def _data(seed: int, scale_um: float, *, directions: bool, z_moved: bool):
    rng = np.random.default_rng(seed)
    n = 120
    axes = np.column_stack([rng.uniform(-60, 60, n), rng.uniform(-40, 40, n),
                            rng.uniform(-20, 20, n) if z_moved else np.zeros(n),
                            rng.choice([-30.0, 0.0, 30.0, 60.0], n), rng.choice(np.arange(0.0, 360.0, 30.0), n)])
    obs = SimpleNamespace(axes=axes, t_s=np.cumsum(rng.uniform(1, 3, n)),
                          directions={"X": rng.choice([-1, 1], n)} if directions else {})
    r_um = scale_um * (rng.normal(size=(n, 3)) + np.sin(2 * np.pi * axes[:, :1] / 10.0))
    return obs, r_um


def _fit(aliases):
    return SimpleNamespace(singular_values=np.geomspace(30.0, 1e-3, 12), rank=12 - len(aliases),
                           param_names=[f"p{i}" for i in range(12)], condition_number=3e4,
                           aliases=[SimpleNamespace(message=m) for m in aliases])


KINDS = {
    "residuals_axes": lambda obs, r, fit, path, frames: plots.plot_residuals_vs_axes(MACHINE, obs, r, path,
                                                                                      frames=frames),
    "residuals_binned": lambda obs, r, fit, path, frames: plots.plot_binned_residuals(MACHINE, obs, r, 1.0, path,
                                                                                       frames=frames),
    "periodogram": lambda obs, r, fit, path, frames: plots.plot_periodogram(MACHINE, obs, r, path, frames=frames),
    "time": lambda obs, r, fit, path, frames: plots.plot_time(obs, r, path, frames=frames),
    "singular_values": lambda obs, r, fit, path, frames: plots.plot_singular_values(fit, path, frames=frames),
}


@pytest.mark.parametrize("kind, kind_before", [(k, k) for k in sorted(KINDS)]
                         + [("residuals_axes", "residuals_binned"), ("residuals_binned", "residuals_axes")])
def test_a_figure_drawn_again_in_a_kept_frame_is_the_figure_drawn_new(kind, kind_before, tmp_path):
    draw = KINDS[kind]
    first = _data(1, 1.0, directions=True, z_moved=False) + (_fit(["EX0C and EY0C: only their sum (B = 0)",
                                                                  "EZ0W held: the board's height"]),)
    second = _data(2, 40.0, directions=False, z_moved=True) + (_fit([]),)
    frames = FigureFrames()
    KINDS[kind_before](*first, tmp_path / "first.png", frames)
    kept = {id(fig) for fig, _ in frames._kept.values()}
    draw(*second, tmp_path / "again.png", frames)
    assert {id(fig) for fig, _ in frames._kept.values()} == kept  # drawn in the same figure
    draw(*second, tmp_path / "new.png", None)
    pixels = {name: np.asarray(Image.open(tmp_path / f"{name}.png")) for name in ("first", "again", "new")}
    assert pixels["again"].shape != pixels["first"].shape or np.any(pixels["again"] != pixels["first"])
    assert pixels["again"].shape == pixels["new"].shape
    assert np.count_nonzero(np.any(pixels["again"] != pixels["new"], axis=-1)) == 0
