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

import io

from ..files import atomic_write

__all__ = ["new_figure", "save_figure", "panel_grid", "legend_below", "SHOWN_WIDTH_IN"]


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
        Crop to the drawn content (``bbox_inches="tight"``).
    """
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight" if tight else None)
    with atomic_write(path, "wb") as f:
        f.write(buf.getvalue())


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
    axs = fig.subplots(rows, cols, sharey=sharey, squeeze=False).ravel()
    for ax in axs[n:]:
        ax.set_visible(False)
    return fig, list(axs[:n])


def legend_below(fig, ax=None, *, columns: int | None = None, fontsize: float = 9, **kwargs):
    """One legend under the figure's panels, where it never covers data: the entries of ``ax`` (an axes or a
    sequence of them; default the figure's first), each label once. Draw it after the layout
    (``fig.tight_layout()``); :func:`save_figure` keeps it."""
    axes = [fig.axes[0]] if ax is None else list(ax) if isinstance(ax, (list, tuple)) else [ax]
    entries = {}
    for a in axes:
        for handle, label in zip(*a.get_legend_handles_labels()):
            entries.setdefault(label, handle)
    if not entries:
        return None
    labels, handles = list(entries), list(entries.values())
    return fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), frameon=False,
                      ncol=columns or min(len(labels), 6), fontsize=fontsize, **kwargs)
