"""Figures for kinid's reports: no pyplot global state, PNG files written whole or not at all.

Figures are :class:`matplotlib.figure.Figure` objects, so making a plot never
switches the user's backend or leaves a figure open in pyplot's registry.

Examples
--------
>>> fig = new_figure((4, 3))
>>> ax = fig.subplots()
>>> _ = ax.plot([0, 1], [0, 1])
>>> save_figure(fig, "line.png")   # doctest: +SKIP
"""
from __future__ import annotations

import functools
import io

from ..files import atomic_write

__all__ = ["new_figure", "save_figure", "panel_grid", "fixed_layout", "legend_below", "text_width_in",
           "SHOWN_WIDTH_IN", "FigureFrames"]


def new_figure(figsize=(7.0, 4.0)):
    """A new figure of ``figsize`` (width, height) inches; add axes with ``fig.subplots(...)``."""
    from matplotlib.figure import Figure

    return Figure(figsize=figsize)


def save_figure(fig, path, *, dpi: int = 110, tight: bool = True) -> None:
    """Render ``fig`` to PNG in memory, then write it to ``path`` atomically.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    path : str or Path
    dpi : int
    tight : bool
        Crop to the drawn content (``bbox_inches="tight"``): matplotlib then draws the figure twice, once to
        measure it. A figure laid out by :func:`fixed_layout` has everything inside it: save it with
        ``tight=False``, drawn once, and written as RGB when every pixel is opaque (a report's figure: the PDF embeds
        it as it is), at zlib level 3 (:func:`_write_png`).
    """
    _ticks_in_view(fig)
    placed = _unlabelled_axes_unmeasured(fig)
    buf = io.BytesIO()
    try:
        if tight:
            fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
        else:
            _write_png(fig, buf, dpi)
    finally:  # a figure drawn again (FigureFrames) may label an axis left empty this time
        for axis, transform, position in placed:
            axis.label.set_transform(transform)
            axis.label.set_position(position)
            axis._autolabelpos = True  # what set_label_coords turned off
    with atomic_write(path, "wb") as f:
        f.write(buf.getvalue())


def _write_png(fig, out, dpi: int) -> None:
    """Draw ``fig`` at ``dpi`` and write it to ``out`` as PNG, as ``fig.savefig(out, format="png", dpi=dpi)`` does
    (the same pixels, resolution and Software note), but without the alpha channel when it is opaque throughout."""
    import matplotlib
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from PIL import Image, PngImagePlugin

    before = fig.dpi
    try:
        fig.set_dpi(dpi)
        # a figure drawn again (FigureFrames) keeps its canvas, whose renderer keeps the sizes of the strings it drew
        canvas = fig.canvas if type(fig.canvas) is FigureCanvasAgg else FigureCanvasAgg(fig)
        canvas.draw()
        rgba = np.asarray(canvas.buffer_rgba())
    finally:
        fig.set_dpi(before)
    note = PngImagePlugin.PngInfo()
    note.add_text("Software", f"Matplotlib version{matplotlib.__version__}, https://matplotlib.org/")
    pixels = rgba[:, :, :3] if np.all(rgba[:, :, 3] == 255) else rgba
    # zlib level 3, not PIL's 6: the demo's 12 PNGs encode in 0.16 s, not 0.27 s, and weigh 1.14 MB, not 1.09 MB
    Image.fromarray(np.ascontiguousarray(pixels)).save(out, format="png", pnginfo=note, dpi=(dpi, dpi),
                                                       compress_level=3)


def _ticks_in_view(fig) -> None:
    """Give every axis of ``fig`` locators that return only the locations inside its view.

    matplotlib makes a tick object (two lines, two texts: about 1 ms each) for every location a locator returns,
    then draws only those inside the view: a log axis's minor locator returns every tick of the decades beyond it
    (20 made, 11 drawn on a period axis from 1 to 60 mm), a linear one a tick past each end. The figure drawn is the
    same; the ticks never drawn are never made.
    """
    from matplotlib.ticker import FixedLocator, NullLocator

    in_view = _in_view_class()
    as_given = (in_view, NullLocator, FixedLocator)  # wrapped (shared axes share locators), none, or chosen by hand
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            if not isinstance(axis.get_major_locator(), as_given):
                axis.set_major_locator(in_view(axis.get_major_locator()))
            if not isinstance(axis.get_minor_locator(), as_given):
                axis.set_minor_locator(in_view(axis.get_minor_locator()))


def _unlabelled_axes_unmeasured(fig) -> list:
    """Fix the place of every empty axis label, which nothing draws: matplotlib otherwise places each label below
    (beside) the tick labels of its axis and of every axis sharing it, measuring them all, at every draw (the
    panels of a row share their y axis and only the first is labelled: 5 panels measured 5 times each).

    Returns (axis, transform, position) of each label fixed, as it was: placed by matplotlib at each draw."""
    placed = []
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            if not axis.label.get_text() and axis._autolabelpos:
                placed.append((axis, axis.label.get_transform(), axis.label.get_position()))
                axis.set_label_coords(0.5, 0.5)
    return placed


@functools.cache
def _in_view_class():
    """The locator class (made on first use: matplotlib is imported only when a figure is drawn)."""
    from matplotlib.ticker import Locator

    class InView(Locator):
        """The locations of ``locator`` that matplotlib would draw: inside the axis's view interval, compared as
        matplotlib's ``Axis._update_ticks`` does (in the scale's coordinates, to 1e-10 of the interval)."""

        def __init__(self, locator):
            self.locator = locator

        def set_axis(self, axis):
            super().set_axis(axis)
            self.locator.set_axis(axis)

        def __call__(self):
            import numpy as np

            locs = np.asarray(self.locator(), float)
            if locs.size == 0 or self.axis is None:
                return locs
            to_scale = self.axis.get_transform()
            lo, hi = sorted(to_scale.transform(sorted(self.axis.get_view_interval())))
            tol = 1e-10 * (hi - lo)
            with np.errstate(invalid="ignore"):
                at = to_scale.transform(locs)
                return locs[(at >= lo - tol) & (at <= hi + tol)]

        def tick_values(self, vmin, vmax):
            return self.locator.tick_values(vmin, vmax)

        def nonsingular(self, v0, v1):
            return self.locator.nonsingular(v0, v1)

        def view_limits(self, vmin, vmax):
            return self.locator.view_limits(vmin, vmax)

    return InView


#: The width a report page shows a figure at (its text column, about 1030 px), in inches at
#: :func:`save_figure`'s 110 dpi. A wider figure is shrunk on the page, and its text with it: figures
#: are drawn at most this wide, so that 8 pt text stays 8 pt where it is read.
SHOWN_WIDTH_IN = 9.3


def panel_grid(n: int, *, panel_in=(3.0, 2.7), most_per_row: int = 3, sharey: bool = True):
    """A figure of ``n`` panels, at most ``most_per_row`` a row (and never wider than :data:`SHOWN_WIDTH_IN`).

    Returns
    -------
    (Figure, list of Axes)
        The ``n`` axes in reading order (a short last row is left empty).
    """
    cols = max(1, min(n, most_per_row))
    rows = -(-n // cols)
    width = min(panel_in[0] * cols, SHOWN_WIDTH_IN)
    fig = new_figure((width, panel_in[1] * rows + 0.5))
    grid = fig.add_gridspec(rows, cols)
    axs = []
    for i in range(n):  # the empty places of a short last row get no axes: an axes costs as much to make as to draw
        ax = fig.add_subplot(grid[i // cols, i % cols], sharey=axs[0] if sharey and axs else None)
        if sharey and i % cols:  # one y scale a row, labelled on its first panel (as subplots(sharey=True) does)
            ax.yaxis.set_tick_params(which="both", labelleft=False)
            ax.yaxis.offsetText.set_visible(False)
        axs.append(ax)
    return fig, axs


class FigureFrames:
    """Figures kept to be drawn again: a report draws the same kinds of figure for its first and its last fit (the
    residuals against the axes, binned, their periodogram, ...), each of the same panels, ticks and labels.

    ``frames.panel_grid(kind, n, ...)`` and ``frames.figure(kind, figsize)`` return the figure last made for ``kind``
    with that layout, emptied of what was plotted in it — its lines, collections, patches, texts, legends and titles
    removed, its axis labels emptied, its data limits, autoscaling, colour cycle and scales reset as a new axes has
    them — or a new one. The
    axes, their tick objects and the canvas, whose renderer keeps the size of every string it has drawn, are made
    once: in matplotlib making an axes and its ticks costs as much as drawing them. The code plotting a kind must set
    everything it shows on every call (labels, ticks, formatters), as it does on a new figure; the tests compare the
    pixels of figures drawn again with those of new ones.
    """

    def __init__(self):
        self._kept = {}

    def panel_grid(self, kind: str, n: int, **kwargs):
        """:func:`panel_grid` ``(n, **kwargs)``, drawn again for ``kind``: (Figure, list of Axes)."""
        key = ("grid", kind, n, tuple(sorted(kwargs.items())))
        if key in self._kept:
            fig, axs = self._kept[key]
            _emptied(fig, fig.get_size_inches())
            return fig, axs
        self._kept[key] = panel_grid(n, **kwargs)
        return self._kept[key]

    def figure(self, kind: str, figsize):
        """A figure of ``figsize`` inches with one axes, drawn again for ``kind``: (Figure, Axes)."""
        key = ("one", kind, tuple(figsize))
        if key in self._kept:
            fig, ax = self._kept[key]
            _emptied(fig, figsize)
            return fig, ax
        fig = new_figure(figsize)
        self._kept[key] = fig, fig.subplots()
        return self._kept[key]


def _emptied(fig, figsize) -> None:
    """Remove what was plotted in ``fig`` and reset its axes' limits, autoscaling, scales and colour cycle as a new
    axes has them (matplotlib's ``Axes.clear`` without its clearing of the axis, which makes the ticks anew)."""
    fig.set_size_inches(figsize)
    for legend in list(fig.legends):
        legend.remove()
    for ax in fig.axes:
        for artist in [*ax.lines, *ax.collections, *ax.patches, *ax.texts, *ax.images, *ax.artists]:
            artist.remove()
        if ax.legend_ is not None:
            ax.legend_.remove()
        for loc in ("center", "left", "right"):
            ax.set_title("", loc=loc)
        ax.set_xlabel("")
        ax.set_ylabel("")
        ax.set_prop_cycle(None)
        ax.set_xscale("linear")
        ax.set_yscale("linear")
        ax.ignore_existing_data_limits = True
        ax.set_xlim(0.0, 1.0, auto=True)
        ax.set_ylim(0.0, 1.0, auto=True)


def fixed_layout(fig, *, left_in: float = 0.75, right_in: float = 0.2, top_in: float = 0.5,
                 bottom_in: float = 0.6, wspace_in: float = 0.25, hspace_in: float = 0.75) -> None:
    """Place the figure's grid of axes with margins and gaps in inches, without measuring its text.

    ``fig.tight_layout()`` and ``save_figure(..., tight=True)`` each draw the whole figure once to measure it
    (tick labels, titles, legends), and matplotlib's text shaping makes a draw costly: a report's figures took
    most of ``kinid demo``'s time. A figure whose text is known (labels of a few characters, a title of one or
    two lines) is laid out here in one step and drawn once.

    Parameters
    ----------
    left_in, right_in, top_in, bottom_in : float
        Margins, inches: the y label and its tick labels (left), the title (top), the x label and its tick
        labels, and a legend placed below by :func:`legend_below` with ``inside=True`` (bottom).
    wspace_in, hspace_in : float
        Gaps between columns and rows of axes, inches (their tick labels and labels).
    """
    w, h = fig.get_size_inches()
    rows, cols = fig.axes[0].get_subplotspec().get_gridspec().get_geometry() if fig.axes else (1, 1)
    axes_w = (w - left_in - right_in - (cols - 1) * wspace_in) / cols
    axes_h = (h - top_in - bottom_in - (rows - 1) * hspace_in) / rows
    fig.subplots_adjust(left=left_in / w, right=1 - right_in / w, top=1 - top_in / h, bottom=bottom_in / h,
                        wspace=wspace_in / axes_w, hspace=hspace_in / axes_h)


def text_width_in(text: str, fontsize: float, *, dpi: int = 110) -> float:
    """Width, inches, of ``text`` (its longest line) set in the figures' font at ``fontsize`` pt and drawn at ``dpi``
    (:func:`save_figure`'s: glyphs are fitted to the pixel grid, so the width depends a little on it): a margin made
    for a note beside the axes, measured without drawing the figure (as ``bbox_inches="tight"`` would)."""
    from matplotlib.backends.backend_agg import RendererAgg
    from matplotlib.font_manager import FontProperties

    measure, prop = RendererAgg(1, 1, dpi), FontProperties(size=fontsize)
    return max(measure.get_text_width_height_descent(line, prop, ismath=False)[0] for line in text.split("\n")) / dpi


def legend_below(fig, ax=None, *, columns: int | None = None, fontsize: float = 9, inside: bool = False, **kwargs):
    """One legend under the figure's panels, where it never covers data: the entries of ``ax`` (an axes or a
    sequence of them; default the figure's first), each label once. Draw it after the layout
    (``fig.tight_layout()``; :func:`save_figure` keeps it), or ``inside`` the figure's bottom edge, in the
    margin :func:`fixed_layout` left for it (``bottom_in``)."""
    axes = [fig.axes[0]] if ax is None else list(ax) if isinstance(ax, (list, tuple)) else [ax]
    entries = {}
    for a in axes:
        for handle, label in zip(*a.get_legend_handles_labels()):
            entries.setdefault(label, handle)
    if not entries:
        return None
    labels, handles = list(entries), list(entries.values())
    where = dict(loc="lower center", bbox_to_anchor=(0.5, 0.0)) if inside else dict(loc="upper center",
                                                                                     bbox_to_anchor=(0.5, 0.0))
    return fig.legend(handles, labels, **where, frameon=False, ncol=columns or min(len(labels), 6), fontsize=fontsize,
                      **kwargs)
