"""Figure geometry as a reader meets it: legends over data, text too small at the size a report shows it.

An independent check of the figures kinid draws (it shares no code with kinid.reports.figures): a report page shows a
figure at most :data:`SHOWN_PX` CSS pixels wide (its text column), so a PNG wider than that is shrunk, and its
text with it. Text must be at least :data:`MIN_PT` points where it is read; a legend must cover no plotted
point (markers, and lines sampled along their segments) of any panel; titles and axis labels must not run into
each other.
"""
import numpy as np
from matplotlib.collections import PathCollection
from matplotlib.text import Text

#: The report page's text column (kinid.reports.html: 1080 px less its padding), CSS px.
SHOWN_PX = 1030
#: The smallest text a reader should meet, points at the displayed size.
MIN_PT = 8.0


def problems(fig, dpi=110, tight=True) -> list:
    """What is wrong with ``fig`` saved at ``dpi`` (cropped to its content if ``tight``), one line each."""
    out = []
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    if not hasattr(fig.canvas, "get_renderer"):
        FigureCanvasAgg(fig)
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    box = fig.get_tightbbox(r) if tight else fig.bbox_inches
    width_px = box.width * dpi
    scale = min(1.0, SHOWN_PX / width_px)
    # pt where read = fontsize · (dpi/72 PNG px per pt) · scale (CSS px per PNG px) · (72/96 pt per CSS px)
    for t in fig.findobj(Text):
        if not t.get_visible() or not t.get_text().strip():
            continue
        shown = t.get_fontsize() * dpi / 96 * scale
        if shown < MIN_PT - 1e-6:
            out.append(f"text {t.get_text()[:30]!r} {t.get_fontsize():.3g} pt shown at {shown:.2f} pt")
    labels = [t for ax in fig.axes if ax.get_visible()
              for t in (ax.title, ax._left_title, ax._right_title, ax.xaxis.label, ax.yaxis.label)]
    if fig._suptitle is not None:
        labels.append(fig._suptitle)
    boxes = [(t, t.get_window_extent(r)) for t in labels if t.get_visible() and t.get_text().strip()]
    for i, (t, b) in enumerate(boxes):
        for u, c in boxes[i + 1:]:
            if b.x0 < c.x1 - 1 and c.x0 < b.x1 - 1 and b.y0 < c.y1 - 1 and c.y0 < b.y1 - 1:
                out.append(f"text {t.get_text()[:30]!r} runs into {u.get_text()[:30]!r}")
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None] + list(fig.legends)
    for lg in legends:
        if not lg.get_visible():
            continue
        lb = lg.get_window_extent(r).shrunk(0.98, 0.98)
        for ax in fig.axes:
            pts = _data_points(ax)
            if pts.size == 0:
                continue
            axb = ax.get_window_extent(r)
            x, y = pts[:, 0], pts[:, 1]
            inside_ax = (x >= axb.x0) & (x <= axb.x1) & (y >= axb.y0) & (y <= axb.y1)
            hit = inside_ax & (x > lb.x0) & (x < lb.x1) & (y > lb.y0) & (y < lb.y1)
            if hit.any():
                names = [t.get_text() for t in lg.get_texts()][:3]
                out.append(f"legend {names} covers {int(hit.sum())} data points of axes {ax.get_title()[:30]!r}")
    return out


def _data_points(ax) -> np.ndarray:
    """Display coordinates of the plotted data of ``ax``: line vertices (and points along drawn segments),
    scatter offsets. Lines in axes coordinates (axhline, axvline) are references, not data."""
    pts = []
    for line in ax.get_lines():
        if not line.get_visible():
            continue
        xy = np.asarray(line.get_xydata(), float)
        if xy.size == 0:
            continue
        if line.get_transform() != ax.transData:
            continue
        xy = xy[np.all(np.isfinite(xy), axis=1)]
        if len(xy) >= 2 and line.get_linestyle() not in ("None", "", " ", "none"):  # points along the segments
            t = np.linspace(0, 1, 8)[:, None, None]
            seg = xy[:-1][None] * (1 - t) + xy[1:][None] * t
            xy = np.concatenate([xy, seg.reshape(-1, 2)])
        pts.append(ax.transData.transform(xy))
    for c in ax.collections:
        if not c.get_visible() or not isinstance(c, PathCollection):
            continue
        off = np.asarray(c.get_offsets(), float)
        if off.size:
            off = off[np.all(np.isfinite(off), axis=1)]
            pts.append(c.get_offset_transform().transform(off))
    return np.concatenate(pts) if pts else np.zeros((0, 2))
