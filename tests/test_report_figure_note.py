"""The singular values' figure holds its note of the parameters held fixed whole: laid out from the note's measured
width (no bbox_inches="tight" crop), every line of it lies inside the saved PNG, and the figure is no wider than the
note needs."""
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

from kinid.identification.reporting.figures import plot_singular_values


@pytest.mark.parametrize("longest", [10, 60, 110])
def test_the_note_of_parameters_held_fixed_lies_inside_the_figure(tmp_path, monkeypatch, longest):
    import kinid.identification.reporting.figures as figures

    messages = [f"E{i}0T " + "w" * (longest - 5) for i in range(3)] + ["EA0T has no effect on these data (held fixed)"]
    fit = SimpleNamespace(singular_values=np.geomspace(2.0, 0.05, 17), rank=17, param_names=["p"] * 23,
                          condition_number=40.0, aliases=[SimpleNamespace(message=m) for m in messages])
    drawn = {}
    real = figures.save_figure

    def save(fig, path, **kwargs):
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        fig.set_dpi(110)  # as saved
        FigureCanvasAgg(fig).draw()
        renderer = fig.canvas.get_renderer()
        drawn["note"] = [t.get_window_extent(renderer) for t in fig.axes[0].texts]
        drawn["figure"], drawn["dpi"], drawn["width_in"] = fig.bbox, fig.dpi, fig.get_size_inches()[0]
        return real(fig, path, **kwargs)

    monkeypatch.setattr(figures, "save_figure", save)
    plot_singular_values(fit, tmp_path / "sv.png")
    (note,), box = drawn["note"], drawn["figure"]
    assert box.x0 <= note.x0 and note.x1 <= box.x1 and box.y0 <= note.y0 and note.y1 <= box.y1
    assert box.x1 - note.x1 < 0.3 * drawn["dpi"]  # and no wide empty margin right of it
    w_px, _ = Image.open(tmp_path / "sv.png").size
    assert abs(w_px - drawn["width_in"] * 110) <= 1  # saved as laid out: not cropped
