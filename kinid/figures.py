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

from .files import atomic_write

__all__ = ["new_figure", "save_figure"]


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
