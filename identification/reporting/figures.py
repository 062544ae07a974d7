"""The figures of the identification reports (PNG, written atomically).

- residuals against each axis position (direction of approach by fill), and binned by position
  against the band where the mean of noise falls;
- residuals against time;
- a Lomb–Scargle periodogram of the residuals against the spatial period of each axis, with the
  candidate periods of the library marked;
- the singular-value spectrum of the column-scaled Jacobian, with the named unidentifiable
  combinations;
- the residual RMS step by step against the noise σ (forward selection);
- measured against model readings, the identified position-dependent errors and maps with their
  ±2σ bands.
"""
from __future__ import annotations

import numpy as np

from kinid.reports.figures import FigureFrames, fixed_layout, legend_below, new_figure, save_figure, text_width_in
from ..model import LINEAR_PERIODS_MM, ROTARY_PERIODS_DEG, basis_of

__all__ = ["plot_maps", "plot_residuals_vs_axes", "plot_time", "plot_periodogram", "plot_singular_values",
           "plot_selection", "plot_measured_vs_model", "plot_identified_errors", "plot_binned_residuals",
           "lomb_scargle_power"]

#: x, y, z residual components: the same colour in every figure.
COMPONENT_COLOURS = ("tab:blue", "tab:orange", "tab:green")

#: The kind of frame (:class:`~kinid.reports.figures.FigureFrames`) of the residuals against the axes and binned: one
#: panel an axis, a y scale a row, each label and title set on every drawing: either is drawn in the other's frame.
RESIDUAL_PANELS = "residual panels"


def plot_residuals_vs_axes(machine, obs, r_um, path, title="Residuals against axis positions", *,
                           frames: FigureFrames | None = None) -> None:
    """One panel per axis: residual components (µm) against the reading.

    The component is told by colour and shape (x blue circles, y orange triangles, z green squares, as in
    the other residual figures); the approach direction of the panel's axis by fill (filled +, hollow −).
    ``frames``: where a report keeps its figures to draw them again (:class:`~kinid.reports.figures.FigureFrames`;
    the other figures of a report take it too).
    """
    fig, axs = (frames or FigureFrames()).panel_grid(RESIDUAL_PANELS, len(machine.axes))
    for j, (ax, a) in enumerate(zip(axs, machine.axes)):
        q = obs.axes[:, j]
        s = obs.directions.get(a.name)
        for comp, (marker, colour) in enumerate(zip("o^s", COMPONENT_COLOURS)):
            label = "xyz"[comp]
            if s is None:
                ax.scatter(q, r_um[:, comp], s=10, marker=marker, color=colour, alpha=0.6,
                           label=label if j == 0 else None)
                continue
            for sign in (1, -1):
                sel = s == sign
                face = colour if sign > 0 else "none"
                ax.scatter(q[sel], r_um[sel, comp], s=10, marker=marker, facecolors=face, edgecolors=colour,
                           linewidths=0.8, alpha=0.7,
                           label=f"{label}, approached {'+' if sign > 0 else '−'}" if j == 0 else None)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xlabel(_position_label(a))
    for ax in axs[::3]:
        ax.set_ylabel("residual (µm)")
    fig.suptitle(f"{title} (workpiece frame)")
    rows = 2 if any(obs.directions.get(a.name) is not None for a in machine.axes[:1]) else 1  # 6 entries: 3 a row
    fixed_layout(fig, bottom_in=0.7 + 0.25 * rows, top_in=0.45)  # the legend's rows below the x labels
    legend_below(fig, axs[0], markerscale=2, inside=True, columns=3)
    save_figure(fig, path, tight=False)


def _position_label(axis) -> str:
    """``X position (mm)``, ``B angle (deg)``: an axis's reading in plain words."""
    return f"{axis.name} position (mm)" if axis.kind == "prismatic" else f"{axis.name} angle (deg)"


def plot_time(obs, r_um, path, *, frames: FigureFrames | None = None) -> bool:
    """Residual components against time; False if the data have no ``t_s``."""
    if obs.t_s is None:
        return False
    fig, ax = (frames or FigureFrames()).figure("time", (7, 3))
    for comp, (marker, colour) in enumerate(zip("o^s", COMPONENT_COLOURS)):
        ax.plot(obs.t_s, r_um[:, comp], marker, ms=2.5, ls="none", color=colour, alpha=0.7, label="xyz"[comp])
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("time since the first alignment (s)")
    ax.set_ylabel("residual (µm)")
    ax.set_title("Residuals against time")
    fixed_layout(fig, bottom_in=0.95, top_in=0.35)
    legend_below(fig, ax, markerscale=2, inside=True)
    save_figure(fig, path, tight=False)
    return True


def lomb_scargle_power(x, y, freqs) -> np.ndarray:
    """Lomb–Scargle power of each column of ``y`` sampled at ``x``, at the angular frequencies ``freqs``.

    The classic periodogram (equal weights, no floating mean: centre ``y`` first), in the units of
    ``scipy.signal.lombscargle(x, y, freqs, normalize=False)``: a harmonic of amplitude A over N samples has
    power about A² N / 4. The sines and cosines, and the phase τ that decouples them, depend on ``x`` only:
    they are computed once for every column.

    Parameters
    ----------
    x : (N,) array
        Sample positions (an axis reading, mm or deg).
    y : (N, K) array
        K signals (residual components, µm).
    freqs : (F,) array
        Angular frequencies, rad per unit of ``x``.

    Returns
    -------
    (F, K) array
        Power, units of ``y`` squared.

    References
    ----------
    Zechmeister M., Kürster M. (2009), The generalised Lomb–Scargle periodogram, A&A 496, 577–584, eq. 5–20
    (with equal weights and no offset; the form SciPy computes).
    """
    x, y = np.asarray(x, float), np.asarray(y, float).reshape(len(x), -1)
    wt = np.multiply.outer(x, np.asarray(freqs, float))  # (N, F)
    n = x.size
    cos_wt, sin_wt = np.cos(wt), np.sin(wt)  # the only sines of (N, F): those of wt − τ follow by the angle sum
    cc = np.mean(cos_wt ** 2, axis=0)
    cs = np.mean(cos_wt * sin_wt, axis=0)
    tau = 0.5 * np.arctan2(2.0 * cs, 2.0 * cc - 1.0)
    cos_tau, sin_tau = np.cos(tau), np.sin(tau)
    cos_t = cos_wt * cos_tau + sin_wt * sin_tau  # cos(wt − τ)
    sin_t = sin_wt * cos_tau - cos_wt * sin_tau  # sin(wt − τ)
    yc, ys = cos_t.T @ y / n, sin_t.T @ y / n  # (F, K)
    tiny = np.finfo(float).epsneg
    c2 = np.maximum(np.mean(cos_t ** 2, axis=0), tiny)[:, None]
    s2 = np.maximum(1.0 - c2, tiny)
    return 2.0 * (yc ** 2 / c2 + ys ** 2 / s2) * n / 4.0


def plot_periodogram(machine, obs, r_um, path, *, frames: FigureFrames | None = None) -> None:
    """Lomb–Scargle power of the residuals against the spatial period of each axis."""
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    fig, axs = (frames or FigureFrames()).panel_grid("periodogram", len(machine.axes), sharey=False)
    centred = r_um[:, :3] - r_um[:, :3].mean(axis=0)
    for j, (ax, a) in enumerate(zip(axs, machine.axes)):
        q = obs.axes[:, j]
        span = np.ptp(q)
        if span <= 0:
            ax.set_title(f"{a.name}: not moved")
            continue
        lo, hi = (1.0, min(60.0, span)) if a.kind == "prismatic" else (20.0, 400.0)
        periods = np.geomspace(lo, max(hi, lo * 2), 600)
        power = lomb_scargle_power(q, centred, 2 * np.pi / periods).sum(axis=1)
        ax.semilogx(periods, power, lw=0.8)
        _candidate_lines(ax, LINEAR_PERIODS_MM if a.kind == "prismatic" else ROTARY_PERIODS_DEG)
        ticks = [1, 2, 5, 10, 20, 50] if a.kind == "prismatic" else [30, 90, 180, 360]
        ax.set_xticks([t for t in ticks if lo <= t <= periods[-1]])
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel(f"period ({'mm' if a.kind == 'prismatic' else 'deg'}) of {a.name}")
    for ax in axs[::3]:
        ax.set_ylabel("Lomb–Scargle power (µm²)")
    fig.suptitle("Residual periodogram (red: candidate periods)")
    fixed_layout(fig, wspace_in=0.55, top_in=0.45)  # each panel's own power tick labels clear of the next
    save_figure(fig, path, tight=False)


def _candidate_lines(ax, periods) -> None:
    """A thin red line across ``ax`` at each period, as ``ax.axvline`` draws it (the x limits take them in), as one
    collection: an ``axvline`` each cost as much as the panel's curve."""
    from matplotlib.collections import LineCollection

    periods = np.asarray(periods, float)
    ax.add_collection(LineCollection([[(p, 0.0), (p, 1.0)] for p in periods], colors="tab:red", linewidths=0.5,
                                     alpha=0.5, transform=ax.get_xaxis_transform()), autolim=False)
    ax.update_datalim(np.column_stack([periods, np.zeros_like(periods)]), updatey=False)


def plot_singular_values(fit_result, path, *, frames: FigureFrames | None = None) -> None:
    """Singular values of the column-scaled Jacobian, and the parameters held fixed (beside the axes, the figure
    widened to their longest line: laid out without drawing it twice to measure it)."""
    fig, ax = (frames or FigureFrames()).figure("singular_values", (7, 3.2))
    s = np.sort(fit_result.singular_values)[::-1]
    from matplotlib.ticker import MaxNLocator

    ax.semilogy(np.arange(1, len(s) + 1), s, "o-", ms=3)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("index (largest first)")
    ax.set_ylabel("singular value (unit columns)")
    ax.set_title(f"Rank {fit_result.rank}/{len(fit_result.param_names)}, condition {fit_result.condition_number:.3g}")
    if fit_result.aliases:  # beside the axes, as wide as the messages
        text = "held fixed:\n" + "\n".join(a.message for a in fit_result.aliases[:8])
        ax.text(1.02, 1.0, text, transform=ax.transAxes, fontsize=8, va="top")
        # the axes as large as matplotlib's default margins leave in 7 × 3.2 in (as these figures were always drawn)
        axes_w_in, axes_h_in = 0.775 * 7, 0.77 * 3.2
        right_in = 0.02 * axes_w_in + text_width_in(text, 8) + 0.1
        fig.set_size_inches(0.75 + axes_w_in + right_in, 0.35 + axes_h_in + 0.5)
        fixed_layout(fig, left_in=0.75, right_in=right_in, top_in=0.35, bottom_in=0.5)
    else:
        fixed_layout(fig, left_in=0.8, top_in=0.35, bottom_in=0.55)
    save_figure(fig, path, tight=False)


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
    longest = max(len(t) for t in labels)  # the tick labels, 8 pt, turned 20°: room below and left of the axes
    fixed_layout(fig, left_in=max(0.75, 0.06 * longest * 0.94 + 0.1), top_in=0.35,
                 bottom_in=0.3 + 0.06 * longest * 0.34 + 0.1)
    save_figure(fig, path, tight=False)


def plot_measured_vs_model(diagnosis, obs, path) -> None:
    """Measured minus model readings of each solved axis, alignment by alignment, a colour per mark
    (no red: red circles mark the outliers)."""
    names = diagnosis.axis_names
    fig = new_figure((9, 1.9 * len(names) + 0.6))
    axs = fig.subplots(len(names), 1, sharex=True, squeeze=False)
    marks = np.asarray(obs.marks)
    colours = ["tab:blue", "tab:green", "tab:purple", "tab:brown", "tab:olive", "tab:cyan", "tab:gray", "tab:pink",
               "tab:orange"]
    for k, (ax, n) in enumerate(zip(axs[:, 0], names)):
        for m_i, mark in enumerate(dict.fromkeys(obs.marks)):
            sel = np.flatnonzero(marks == mark)
            ax.plot(sel + 1, diagnosis.axis_residuals_um[sel, k], ".", ms=3, color=colours[m_i % len(colours)],
                    label=mark if k == 0 and m_i < 12 else None)
        for i in diagnosis.outliers:
            ax.plot(i + 1, diagnosis.axis_residuals_um[i, k], "o", mfc="none", mec="tab:red", ms=8)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_ylabel(f"{n} (µm)")
    axs[-1, 0].set_xlabel("alignment number" + (" (red circles: possible outliers)" if len(diagnosis.outliers) else ""))
    # the marks' legend above the panels, never over the points
    axs[0, 0].legend(fontsize=8, ncol=min(len(dict.fromkeys(obs.marks)), 12), markerscale=3, loc="lower left",
                     bbox_to_anchor=(0.0, 1.02), frameon=False, title="mark", title_fontsize=8)
    fig.suptitle("Measured minus model readings")
    save_figure(fig, path)


def plot_maps(fit_result, path) -> bool:
    """Each map effect of the fit: the error at its knots with a ±2σ band, against its axis. False if none."""
    maps = [e for e in fit_result.effects if basis_of(e).knots_plot]  # local errors: plot_identified_errors draws them
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
        ax.fill_between(q[ok], (v - 2 * sd)[ok], (v + 2 * sd)[ok], color="tab:blue", alpha=0.25)
        ax.plot(q[ok], v[ok], "o-", color="tab:blue", ms=3)
        ax.axhline(0.0, color="0.5", lw=0.8)
        ax.set_xlabel(f"{e.axis} position ({axis_unit})")
        ax.set_ylabel(f"{e.code} ({unit})")
        ax.set_title(f"{e.name}: identified map at its knots, band ±2σ (k = 2)\n(the part the location errors "
                     f"do not hold)", fontsize=10)
    save_figure(fig, path)
    return True


def _covariance(fit_result, obs) -> np.ndarray:
    """Covariance of the parameters (P, P), zero rows for held ones: the fit's standard deviations with the
    correlations of the Jacobian at the fit."""
    from ..fitting import design, residuals

    machine = fit_result.machine
    d = design(machine, fit_result.effects, obs)
    _, J, _ = residuals(machine, d, obs, fit_result.theta)
    ok = np.asarray(fit_result.identifiable, bool)
    A = J.reshape(-1, J.shape[2])[:, ok]
    inv = np.linalg.pinv(A.T @ A)
    sd = np.sqrt(np.clip(np.diag(inv), 1e-300, None))
    corr = inv / np.outer(sd, sd)
    std = np.nan_to_num(np.asarray(fit_result.std, float)[ok])
    cov = np.zeros((ok.size, ok.size))
    cov[np.ix_(ok, ok)] = corr * np.outer(std, std)
    return cov


def _varying_joints(fit_result) -> dict:
    """(error code, axis) -> list of (effect, parameter slice) for effects driven by an axis position (a step at
    another axis's position is a curve over that axis)."""
    out, k = {}, 0
    for e in fit_result.effects:
        if basis_of(e).positional:
            out.setdefault((e.code, e.axis), []).append((e, slice(k, k + e.n_params)))
        k += e.n_params
    return out


def _basis_at(machine, parts, axis: str, x, n_params: int) -> np.ndarray:
    """The model's columns (len(x), n_params) of the effects ``parts`` ((effect, its slice of the parameters)) with
    ``axis`` at positions ``x`` and every other axis at zero."""
    from ..model import basis_values

    poses = np.zeros((x.size, len(machine.axes)))
    poses[:, machine.axis_names.index(axis)] = x
    B = np.zeros((x.size, n_params))
    for e, sl in parts:
        B[:, sl] = basis_values(e, machine, poses)
    return B


#: An axis read at this many distinct positions or fewer has them marked on its identified errors.
MARKED_POSITIONS = 20


def plot_identified_errors(fit_result, obs, path) -> bool:
    """Each identified position-dependent error against its axis over the measured range, with its ±2σ
    band (k = 2, from the parameters' covariance), and the positions measured where they are few (between them
    the curve is the model's, not a measurement). False if the model has none."""
    from ..data import distinct_positions

    joints = _varying_joints(fit_result)
    if not joints:
        return False
    machine = fit_result.machine
    cov = _covariance(fit_result, obs)
    theta = fit_result.theta
    fig = new_figure((7.5, 2.9 * len(joints) + 0.4))
    axes = fig.subplots(len(joints), 1, squeeze=False)[:, 0]
    for ax, ((code, axis), parts) in zip(axes, joints.items()):
        q = obs.axes[:, machine.axis_names.index(axis)]
        grid = np.linspace(np.nanmin(q), np.nanmax(q), 600)
        B = _basis_at(machine, parts, axis, grid, theta.size)
        value = B @ theta
        band = 2 * np.sqrt(np.clip(np.einsum("np,pq,nq->n", B, cov, B), 0, None))
        unit = "µm" if parts[0][0].unit == "um" else "µrad"
        axis_unit = "mm" if machine.axis(axis).kind == "prismatic" else "deg"
        ax.fill_between(grid, value - band, value + band, color="tab:blue", alpha=0.25)
        ax.plot(grid, value, color="tab:blue", lw=1.4)
        measured = distinct_positions(q[np.isfinite(q)])
        if measured.size <= MARKED_POSITIONS:  # few: where the curve is measured, and where it only joins them
            at = _basis_at(machine, parts, axis, measured, theta.size) @ theta
            ax.plot(measured, at, "o", ms=4.5, color="tab:blue", label=f"the {measured.size} positions measured")
            ax.legend(loc="best", fontsize=8, frameon=False)
        ax.axhline(0, color="0.5", lw=0.8)
        ax.set_xlabel(f"{axis} position ({axis_unit})")
        ax.set_ylabel(f"{code} ({unit})")
        from ..model import axis_directions, plain_name

        ax.set_title(f"{code}: {plain_name(code, axis_directions(machine))}\n"
                     f"{' + '.join(e.name for e, _ in parts)}, band ±2σ (k = 2)", fontsize=10)
    fixed_layout(fig, left_in=0.85, top_in=0.5, bottom_in=0.5, hspace_in=1.05)  # two-line titles above each panel
    save_figure(fig, path, tight=False)
    return True


def plot_binned_residuals(machine, obs, r_um, sigma_um, path, *, labels=("x", "y", "z"),
                          what="residual in the workpiece frame", frames: FigureFrames | None = None) -> None:
    """Mean residual per bin of each axis position, each component, against the noise band ±2σ/√n:
    structure the scatter hides (a periodic error of a few µm) stands out of the band.

    Bins: each preset position of an axis read at 16 positions or fewer; else equal-width bins, about
    8 readings each (at most 40), so that a lead error of a few mm shows as a wave.
    """
    fig, axs = (frames or FigureFrames()).panel_grid(RESIDUAL_PANELS, len(machine.axes))
    for j, (ax, a) in enumerate(zip(axs, machine.axes)):
        q = obs.axes[:, j]
        values = np.unique(q[np.isfinite(q)])
        if values.size <= 16:  # preset positions (rotary axes of a plan): one bin each
            centres = values
            which = np.searchsorted(values, q)
        else:
            n_bins = int(np.clip(q.size // 8, 8, 40))
            edges = np.linspace(values[0], values[-1], n_bins + 1)
            centres = 0.5 * (edges[:-1] + edges[1:])
            which = np.clip(np.searchsorted(edges, q, side="right") - 1, 0, n_bins - 1)
        counts = np.array([(which == b).sum() for b in range(len(centres))])
        keep = counts > 0
        half = 2 * sigma_um / np.sqrt(np.maximum(counts, 1))
        ax.fill_between(centres[keep], -half[keep], half[keep], color="0.85", step="mid", label="±2σ/√n")
        for comp in range(r_um.shape[1]):
            mean = np.array([r_um[which == b, comp].mean() if counts[b] else np.nan for b in range(len(centres))])
            ax.plot(centres[keep], mean[keep], "o-", ms=3, lw=1, color=COMPONENT_COLOURS[comp % 3], label=labels[comp])
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xlabel(_position_label(a))
    for ax in axs[::3]:
        ax.set_ylabel("mean per bin (µm)")
    fig.suptitle(f"{what[0].upper() + what[1:]}, binned by axis position\n(grey: where the mean of noise "
                 f"σ = {sigma_um:.3g} µm falls)")
    fixed_layout(fig, bottom_in=0.95, top_in=0.7)  # a two-line title; one legend row below the x labels
    legend_below(fig, axs[0], inside=True)
    save_figure(fig, path, tight=False)
