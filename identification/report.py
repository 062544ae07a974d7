"""Pictures and an HTML page: where the model fails, and the error falling as effects are added.

Plots (PNG, written atomically):

- residuals against each axis position, coloured by approach direction;
- residuals against time;
- a Lomb–Scargle periodogram of the residuals against the spatial period of
  each axis, with the candidate periods of the library marked;
- the singular-value spectrum of the column-scaled Jacobian, with the named
  unidentifiable combinations;
- the residual RMS step by step against the noise σ (forward selection).
"""
from __future__ import annotations

import html
from pathlib import Path

import numpy as np

from kinid.files import write_text
from .effects import LINEAR_PERIODS_MM, ROTARY_PERIODS_DEG
from kinid.errors import DataError
from kinid.figures import new_figure, save_figure

__all__ = ["diagnosis_report", "selection_report", "plot_maps", "plot_residuals_vs_axes", "plot_periodogram", "plot_singular_values", "plot_selection"]


def _outdir(folder) -> Path:
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DataError(f"cannot create the report folder ({exc.strerror})", path=folder) from None
    return folder


def plot_residuals_vs_axes(machine, obs, r_um, path, title="Residuals against axis positions") -> None:
    """One panel per axis: residual components (µm) against the reading, coloured by approach direction."""
    n = len(machine.axes)
    fig = new_figure((3.2 * n, 3.2))
    axs = fig.subplots(1, n, sharey=True, squeeze=False)
    for j, (ax, a) in enumerate(zip(axs[0], machine.axes)):
        q = obs.axes[:, j]
        s = obs.directions.get(a.name)
        for comp, marker in zip(range(3), "o^s"):
            if s is None:
                ax.scatter(q, r_um[:, comp], s=6, marker=marker, alpha=0.6, label="xyz"[comp])
            else:
                for sign, colour in ((1, "tab:blue"), (-1, "tab:orange")):
                    sel = s == sign
                    ax.scatter(q[sel], r_um[sel, comp], s=6, marker=marker, color=colour, alpha=0.6,
                               label=f"{'xyz'[comp]}, dir {'+' if sign > 0 else '−'}" if j == 0 else None)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xlabel(a.column)
    axs[0, 0].set_ylabel("residual (µm), workpiece frame")
    axs[0, 0].legend(fontsize=6, markerscale=2)
    fig.suptitle(title)
    save_figure(fig, path)


def plot_time(obs, r_um, path) -> bool:
    """Residual components against time; False if the data have no ``t_s``."""
    if obs.t_s is None:
        return False
    fig = new_figure((7, 3))
    ax = fig.subplots()
    for comp in range(3):
        ax.plot(obs.t_s, r_um[:, comp], ".", ms=3, label="xyz"[comp])
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("residual (µm)")
    ax.legend(fontsize=7)
    ax.set_title("Residuals against time")
    save_figure(fig, path)
    return True


def plot_periodogram(machine, obs, r_um, path) -> None:
    """Lomb–Scargle power of the residuals against the spatial period of each axis."""
    from scipy.signal import lombscargle

    n = len(machine.axes)
    fig = new_figure((3.2 * n, 3.0))
    axs = fig.subplots(1, n, squeeze=False)
    for j, (ax, a) in enumerate(zip(axs[0], machine.axes)):
        q = obs.axes[:, j]
        span = np.ptp(q)
        if span <= 0:
            ax.set_title(f"{a.name}: not moved")
            continue
        lo, hi = (1.0, min(60.0, span)) if a.kind == "prismatic" else (20.0, 400.0)
        periods = np.geomspace(lo, max(hi, lo * 2), 600)
        w = 2 * np.pi / periods
        power = sum(lombscargle(q, r_um[:, c] - r_um[:, c].mean(), w, normalize=False) for c in range(3))
        ax.semilogx(periods, power, lw=0.8)
        for p in LINEAR_PERIODS_MM if a.kind == "prismatic" else ROTARY_PERIODS_DEG:
            ax.axvline(p, color="tab:red", lw=0.5, alpha=0.5)
        from matplotlib.ticker import NullFormatter, ScalarFormatter

        ticks = [1, 2, 5, 10, 20, 50] if a.kind == "prismatic" else [30, 90, 180, 360]
        ax.set_xticks([t for t in ticks if lo <= t <= periods[-1]])
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel(f"period ({'mm' if a.kind == 'prismatic' else 'deg'}) of {a.name}")
    axs[0, 0].set_ylabel("Lomb–Scargle power (µm²)")
    fig.suptitle("Residual periodogram (red: candidate periods)")
    save_figure(fig, path)


def plot_singular_values(fit_result, path) -> None:
    """Singular values of the column-scaled Jacobian, and the parameters held fixed."""
    fig = new_figure((7, 3.2))
    ax = fig.subplots()
    s = np.sort(fit_result.singular_values)[::-1]
    ax.semilogy(np.arange(1, len(s) + 1), s, "o-", ms=3)
    ax.set_xlabel("index")
    ax.set_ylabel("singular value (unit columns)")
    ax.set_title(f"Rank {fit_result.rank}/{len(fit_result.param_names)}, condition {fit_result.condition_number:.3g}")
    if fit_result.aliases:
        text = "\n".join(a.message for a in fit_result.aliases[:8])
        ax.text(1.02, 1.0, "held fixed:\n" + text, transform=ax.transAxes, fontsize=6, va="top")
    save_figure(fig, path)


def plot_selection(steps, path) -> None:
    """Residual RMS per step of forward selection against the noise σ."""
    fig = new_figure((7, 3.4))
    ax = fig.subplots()
    rms = [s.diagnosis.rms_um for s in steps]
    labels = ["default model"] + [f"+ {s.added}" for s in steps[1:]]
    ax.plot(range(len(rms)), rms, "o-", label="residual RMS")
    sigma = steps[-1].diagnosis.noise_um
    ax.axhline(sigma, color="tab:green", ls="--", label=f"noise σ = {sigma:.3g} µm")
    ax.set_xticks(range(len(rms)), labels, rotation=20, ha="right", fontsize=8)
    ax.set_ylabel("µm per coordinate")
    ax.set_ylim(0, max(rms) * 1.15)
    ax.legend()
    ax.set_title("The error falls as effects are added")
    save_figure(fig, path)


def _figures(prefix, machine, obs, fit_result, folder: Path):
    r = fit_result.residuals_um
    figs = []
    plot_residuals_vs_axes(machine, obs, r, folder / f"{prefix}residuals_axes.png")
    figs.append(("Residuals against axis positions", f"{prefix}residuals_axes.png"))
    if plot_time(obs, r, folder / f"{prefix}residuals_time.png"):
        figs.append(("Residuals against time", f"{prefix}residuals_time.png"))
    plot_periodogram(machine, obs, r, folder / f"{prefix}periodogram.png")
    figs.append(("Residual periodogram", f"{prefix}periodogram.png"))
    plot_singular_values(fit_result, folder / f"{prefix}singular_values.png")
    figs.append(("Singular values and held parameters", f"{prefix}singular_values.png"))
    return figs


def _page(title, sections) -> str:
    body = [f"<h1>{html.escape(title)}</h1>"]
    for heading, text, figs in sections:
        body.append(f"<h2>{html.escape(heading)}</h2>")
        if text:
            body.append(f"<pre>{html.escape(text)}</pre>")
        for caption, name in figs:
            body.append(f'<figure><img src="{name}" alt="{html.escape(caption)}"><figcaption>{html.escape(caption)}</figcaption></figure>')
    style = "body{font-family:sans-serif;max-width:1200px;margin:auto}pre{background:#f4f4f4;padding:8px;font-size:12px}img{max-width:100%}"
    return f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title><style>{style}</style></head><body>{''.join(body)}</body></html>\n"


def residuals_csv(diagnosis, obs) -> str:
    """One row per alignment: pose, residual in the workpiece frame and in axis readings (µm), outlier statistics."""
    machine = diagnosis.fit.machine
    axes = [a for a in machine.axes]
    header = ["row", "mark", *[a.column for a in axes], "r_x_um", "r_y_um", "r_z_um",
              *[f"d{n.lower()}_um" for n in diagnosis.axis_names], "studentized", "leverage", "outlier"]
    lines = [",".join(header)]
    out = set(diagnosis.outliers)
    for i in range(len(obs)):
        row = [str(i + 1), obs.marks[i], *(f"{v:.6f}" for v in obs.axes[i])]
        row += [f"{v:.4f}" for v in diagnosis.fit.residuals_um[i]]
        row += [f"{v:.4f}" for v in diagnosis.axis_residuals_um[i]]
        row += [f"{diagnosis.studentized[i]:.3f}", f"{diagnosis.leverage[i]:.4f}", "1" if i in out else "0"]
        lines.append(",".join(row))
    return "\n".join(lines) + "\n"


def plot_measured_vs_model(diagnosis, obs, path) -> None:
    """Measured minus model readings of each solved axis, alignment by alignment, coloured by mark."""
    names = diagnosis.axis_names
    fig = new_figure((9, 1.9 * len(names)))
    axs = fig.subplots(len(names), 1, sharex=True, squeeze=False)
    marks = np.asarray(obs.marks)
    for k, (ax, n) in enumerate(zip(axs[:, 0], names)):
        for mark in dict.fromkeys(obs.marks):
            sel = np.flatnonzero(marks == mark)
            ax.plot(sel + 1, diagnosis.axis_residuals_um[sel, k], ".", ms=3, label=mark if k == 0 else None)
        for i in diagnosis.outliers:
            ax.plot(i + 1, diagnosis.axis_residuals_um[i, k], "o", mfc="none", mec="tab:red", ms=7)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_ylabel(f"{n} (µm)")
    axs[-1, 0].set_xlabel("alignment (red circles: outliers)")
    axs[0, 0].legend(fontsize=6, ncol=8, markerscale=3)
    fig.suptitle("Measured minus model readings")
    save_figure(fig, path)


def diagnosis_report(diagnosis, obs, folder) -> Path:
    """Write the plots, ``residuals.csv`` and ``index.html`` of one diagnosis into ``folder``; returns the page's path."""
    folder = _outdir(folder)
    machine = diagnosis.fit.machine
    figs = _figures("", machine, obs, diagnosis.fit, folder)
    write_text(folder / "residuals.csv", residuals_csv(diagnosis, obs))
    if diagnosis.axis_names and np.all(np.isfinite(diagnosis.axis_residuals_um)):
        plot_measured_vs_model(diagnosis, obs, folder / "measured_vs_model.png")
        figs.append(("Measured minus model readings (table: residuals.csv)", "measured_vs_model.png"))
    if plot_maps(diagnosis.fit, folder / "maps.png"):
        figs.append(("Identified error maps with ±2σ band", "maps.png"))
    page = folder / "index.html"
    write_text(page, _page("kinid diagnosis", [("Diagnosis", diagnosis.text(top=15), figs), ("Fit", diagnosis.fit.table(), [])]))
    return page


def plot_maps(fit_result, path) -> bool:
    """Each map effect of the fit: the error at its knots with a ±2σ band, against its axis. False if none."""
    maps = [e for e in fit_result.effects if e.basis == "map"]
    if not maps:
        return False
    fig = new_figure((7.0, 3.0 * len(maps)))
    axes = fig.subplots(len(maps), 1, squeeze=False)[:, 0]
    fig.subplots_adjust(hspace=0.55)
    for ax, e in zip(axes, maps):
        k = fit_result.effects.index(e)
        start = sum(x.n_params for x in fit_result.effects[:k])
        v = fit_result.values[start:start + e.n_params]
        sd = fit_result.std[start:start + e.n_params]
        q = np.asarray(e.knots)
        unit = "µm" if e.unit == "um" else "µrad"
        axis_unit = "mm" if fit_result.machine.axis(e.axis).kind == "prismatic" else "deg"
        ok = np.isfinite(v)
        ax.fill_between(q[ok], (v - 2 * sd)[ok], (v + 2 * sd)[ok], color="tab:blue", alpha=0.25, label="±2σ")
        ax.plot(q[ok], v[ok], "o-", color="tab:blue", ms=3, label=f"{e.code} at the knots")
        ax.axhline(0.0, color="0.5", lw=0.8)
        ax.set_xlabel(f"{e.axis} position ({axis_unit})")
        ax.set_ylabel(f"{e.code} ({unit})")
        ax.set_title(f"{e.name}: identified map (the part the location errors do not hold)", fontsize=10)
        ax.legend(fontsize=8, loc="best")
    save_figure(fig, path)
    return True


def selection_report(steps, obs, folder, *, preface: str = "") -> Path:
    """Write the forward-selection report (falling error, first and last residual plots) into ``folder``."""
    folder = _outdir(folder)
    machine = steps[0].fit.machine
    plot_selection(steps, folder / "rms_steps.png")
    sections = [("The error falls as effects are added", preface, [("Residual RMS per step against σ", "rms_steps.png")])]
    first = steps[0].data if getattr(steps[0], "data", None) is not None else obs  # gross errors set aside
    last = steps[-1].data if getattr(steps[-1], "data", None) is not None else obs
    sections.append(("Default model: where it fails", steps[0].diagnosis.text(top=10), _figures("before_", machine, first, steps[0].fit, folder)))
    if len(steps) > 1:
        sections.append(("Final model", steps[-1].diagnosis.text(top=5), _figures("after_", machine, last, steps[-1].fit, folder)))
    if plot_maps(steps[-1].fit, folder / "maps.png"):
        sections.append(("Non-parametric error maps", "", [("Identified maps with ±2σ band", "maps.png")]))
    write_text(folder / "residuals.csv", residuals_csv(steps[-1].diagnosis, last))
    sections.append(("Final fit", steps[-1].fit.table(), []))
    page = folder / "index.html"
    write_text(page, _page("kinid: compare, diagnose, add, watch the error fall", sections))
    return page
