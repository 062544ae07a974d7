"""A machine's history as a table (``kinid history show``) and as trends with their uncertainty (``plot``)."""
from __future__ import annotations

import datetime as _dt

from kinid.reports.figures import panel_grid, save_figure
from .history import History

__all__ = ["history_text", "plot_history"]

#: The chance that a term that did not move is flagged between two calibrations at k = 2 (two-sided normal).
CHANCE_K2 = 0.0455


def _cell(v, s) -> str:
    if v is None:
        return "—"
    return f"{v:.4g}" + ("" if s is None else f" ±{2 * s:.2g}")


def history_text(history: History, *, last: int | None = None) -> str:
    """The history as a table: a row per term, a column per calibration (value ± its expanded uncertainty,
    k = 2), the trend per year and the flag; then why each flagged term is flagged.

    ``last`` shows only the latest ``last`` calibrations' columns (the flags and trends use them all).
    """
    cols = list(range(len(history.dates)))[-last:] if last else list(range(len(history.dates)))
    h = history
    lines = [f"history of machine {h.machine_id} in {h.database}: {len(h.dates)} calibration"
             f"{'s' if len(h.dates) != 1 else ''}, {h.dates[0]} .. {h.dates[-1]}",
             f"values ± expanded uncertainty (k = 2); * flagged: moved beyond k·√(σ₁² + σ₂²), k = {h.k:g}, "
             f"between consecutive calibrations" + (", or beyond a tolerance given" if h.tolerances else "")]
    width = max([len(t.name) for t in h.terms] + [12])
    header = f"  {'term':<{width}} {'unit':<5}" + "".join(f" {h.dates[i]:>16}" for i in cols) + f" {'trend /year':>16}"
    for kind, title in (("machine", "machine errors"), ("setup", "set-up of the board and the sensor (new at every "
                                                                "set-up: flagged only by a tolerance)")):
        terms = [t for t in h.terms if t.kind == kind]
        if not terms:
            continue
        lines += ["", title + ":", header]
        for t in terms:
            trend = "" if t.trend_per_year is None else _cell(t.trend_per_year, t.trend_std_per_year)
            lines.append(f"{'*' if t.flagged else ' '} {t.name:<{width}} {t.unit:<5}"
                         + "".join(f" {_cell(t.values[i], t.std[i]):>16}" for i in cols) + f" {trend:>16}")
    verified = [(d, c["verify"]) for d, c in zip(h.dates, h.calibrations) if c["verify"]]
    if verified:
        lines += ["", "verification after loading each compensation (kinid verify), 3-D RMS in µm:"]
        lines += [f"  {d}: before {v['before_3d_um']:.3g}, after {v['after_3d_um']:.3g}, noise alone "
                  f"{v['noise_level_3d_um']:.3g}" + (" (at the noise level)" if v["at_noise_level"] else
                                                      " (error remains)") for d, v in verified]
    flagged = h.flagged
    lines.append("")
    if flagged:
        lines.append(f"flagged: {', '.join(t.name for t in flagged)}")
        for t in flagged:
            lines += [f"  {t.name}: {why}" for why in t.flags]
    else:
        lines.append("flagged: none")
    if h.comparisons:
        lines.append(f"(at k = {h.k:g} a term that did not move is flagged in about {CHANCE_K2:.1%} of comparisons "
                     f"by chance: {h.comparisons} comparisons here, about {CHANCE_K2 * h.comparisons:.1f} expected)"
                     if h.k == 2 else f"({h.comparisons} comparisons of consecutive calibrations)")
    return "\n".join(lines)


def plot_history(history: History, path, *, every_term: bool = False) -> int:
    """Each flagged term (every term with ``every_term``) over time with its expanded uncertainty (k = 2) as
    bars, one panel per term, to the PNG ``path``; returns the number of panels."""
    from matplotlib.dates import AutoDateLocator, ConciseDateFormatter

    # a term no calibration identified has nothing to draw
    terms = [t for t in history.terms if (every_term or t.flagged) and any(v is not None for v in t.values)]
    dates = [_dt.date.fromisoformat(d) for d in history.dates]
    fig, axs = panel_grid(max(len(terms), 1), panel_in=(3.1, 2.4), sharey=False)
    fig.set_layout_engine("constrained")
    if not terms:
        axs[0].text(0.5, 0.5, f"no term of {history.machine_id} flagged\n(--all plots every term)",
                    ha="center", va="center", transform=axs[0].transAxes)
        axs[0].set_axis_off()
    for ax, t in zip(axs, terms):
        pts = [(d, v, s) for d, v, s in zip(dates, t.values, t.std) if v is not None]
        if pts:
            ax.errorbar([p[0] for p in pts], [p[1] for p in pts],
                        yerr=[0.0 if p[2] is None else 2 * p[2] for p in pts], fmt="o-",
                        color="tab:red" if t.flagged else "tab:blue", capsize=3, lw=1, ms=4)
        ax.set_title(f"{t.name}{' (set-up)' if t.kind == 'setup' else ''}{' (flagged)' if t.flagged else ''}",
                     fontsize=9)
        ax.set_ylabel(t.unit, fontsize=8)
        ax.tick_params(labelsize=7)
        locator = AutoDateLocator(minticks=2, maxticks=4)
        ax.xaxis.set_major_locator(locator)
        ax.xaxis.set_major_formatter(ConciseDateFormatter(locator))
        ax.grid(alpha=0.3)
    fig.suptitle(f"machine {history.machine_id}: {'terms' if every_term else 'flagged terms'} over "
                 f"{len(dates)} calibrations, bars ±2σ (k = 2)", fontsize=10)
    save_figure(fig, path)
    return len(terms)
