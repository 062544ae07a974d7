"""The HTML reports of identify, diagnose and demo: where the model fails, and the error falling as
effects are added — tables, summary and page (the figures: :mod:`~kinid.identification.reporting.figures`).

A report folder is written whole or not at all (:func:`kinid.reports.html.report_folder`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from kinid.files import write_text
from kinid.errors import DataError
from kinid.reports.figures import FigureFrames
from kinid.reports.html import Figure, Section, Table, report_folder, write_report
from ..diagnosis import ALPHA
from .figures import (plot_binned_residuals, plot_identified_errors, plot_maps, plot_measured_vs_model,
                      plot_periodogram, plot_residuals_vs_axes, plot_selection, plot_singular_values, plot_time)

__all__ = ["diagnosis_report", "selection_report", "plot_maps", "plot_residuals_vs_axes", "plot_periodogram",
           "plot_singular_values", "plot_selection", "plot_identified_errors", "plot_binned_residuals", "errors_table",
           "tool_motion_um"]


def _outdir(folder) -> Path:
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DataError(f"cannot create the report folder ({exc.strerror})", path=folder) from None
    return folder


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


def _figures(prefix, machine, obs, fit_result, folder: Path, diagnosis=None, frames=None):
    """The residual figures of one fit, into ``folder``; ``frames``: a report's figures kept to be drawn again
    (:class:`~kinid.reports.figures.FigureFrames`: a selection report draws these for its first and last fit)."""
    r = fit_result.residuals_um
    figs = []
    if diagnosis is not None and diagnosis.axis_names and np.all(np.isfinite(diagnosis.axis_residuals_um)):
        # readings of the solved axes, measured − model: an axis's own error shows in its own reading
        plot_binned_residuals(machine, obs, diagnosis.axis_residuals_um, fit_result.noise_um,
                              folder / f"{prefix}residuals_binned.png",
                              labels=tuple(f"{n} reading" for n in diagnosis.axis_names),
                              what="measured − model reading of the solved axes", frames=frames)
    else:
        plot_binned_residuals(machine, obs, r, fit_result.noise_um, folder / f"{prefix}residuals_binned.png",
                              frames=frames)
    figs.append(Figure(f"{prefix}residuals_binned.png", "Mean residual per bin of each axis position, against the "
                       "band where the mean of pure noise falls (95 %)"))
    plot_residuals_vs_axes(machine, obs, r, folder / f"{prefix}residuals_axes.png", frames=frames)
    figs.append(Figure(f"{prefix}residuals_axes.png", "Every residual against the axis positions"))
    if plot_time(obs, r, folder / f"{prefix}residuals_time.png", frames=frames):
        figs.append(Figure(f"{prefix}residuals_time.png", "Residuals against time"))
    plot_periodogram(machine, obs, r, folder / f"{prefix}periodogram.png", frames=frames)
    figs.append(Figure(f"{prefix}periodogram.png", "Residual periodogram (red lines: the library's periods)"))
    plot_singular_values(fit_result, folder / f"{prefix}singular_values.png", frames=frames)
    figs.append(Figure(f"{prefix}singular_values.png", "Singular values of the scaled Jacobian, and the parameters "
                       "held fixed"))
    return figs


def _fmt(v: float, u: float) -> tuple:
    """Value and expanded uncertainty as strings with the uncertainty's two significant digits."""
    if not np.isfinite(u) or u <= 0:
        return f"{v:.4g}", "—"
    digits = max(0, 1 - int(np.floor(np.log10(u))))
    return f"{v:.{digits}f}", f"{u:.{digits}f}"


def errors_table(fit_result, *, caption="", obs=None) -> Table:
    """The identified parameters: code, plain name, how it varies, value, unit, U (k = 2).

    With ``obs``, each position-dependent error also says over which part of its axis's travel it was
    measured: outside that range the identified curve is an extrapolation.
    """
    from ..model import axis_limits
    from ..model import axis_directions, effect_description, plain_name

    machine = fit_result.machine
    axes = axis_directions(machine)
    limits = axis_limits(machine)
    flagged = {a.effect: a for a in fit_result.implausible()}
    rows, k = [], 0
    for e in fit_result.effects:
        axis_unit = ""
        if e.axis:
            axis_unit = "mm" if machine.axis(e.axis).kind == "prismatic" else "deg"
        how = effect_description(e, axis_unit)
        if e.axis and obs is not None:
            how += "; " + _coverage(e.axis, obs, machine, limits, axis_unit)
        what = plain_name(e.code, axes)
        names = e.param_names()
        for i, name in enumerate(names):
            unit = fit_result.units[k + i].replace("um", "µm").replace("urad", "µrad")
            if fit_result.identifiable[k + i]:
                v, u = _fmt(fit_result.values[k + i], 2 * fit_result.std[k + i])
            else:
                v, u = "held", "—"
            term = name[name.find("[") + 1:-1] if len(names) > 1 and name.endswith("]") else ""
            what_text = f"{what}, {term} term" if term else what
            if e.name in flagged and i == 0:
                what_text += " (⚠ a size no machine has: see below the table)"
            rows.append((name, what_text, how if i == 0 else "as above", v, u, unit))
        k += e.n_params
    notes = [f"⚠ {a.describe()}: {a.remedy}" for a in flagged.values()]
    return Table(("error", "what it is", "how it varies", "value", "U (k = 2)", "unit"), tuple(rows), numeric=(3, 4),
                 caption=(caption or "U: expanded uncertainty, k = 2 (twice the standard deviation at the σ used); "
                                     "held: not identifiable from these data (see below)")
                 + "".join(f". {n}" for n in notes))


def _coverage(axis: str, obs, machine, limits, unit: str) -> str:
    """``measured over X −67.6 to 67.6 mm of its travel −600 to 600 mm (11 %)``."""
    j = [a.name for a in machine.axes].index(axis)
    q = obs.axes[:, j]
    q = q[np.isfinite(q)]
    if q.size == 0:
        return "not measured"
    lo, hi = float(q.min()), float(q.max())
    text = f"measured over {axis} {lo:.4g} to {hi:.4g} {unit}".replace("-", "−")
    t_lo, t_hi = limits[j]
    if np.isfinite(t_lo) and np.isfinite(t_hi):
        share = 100 * (hi - lo) / (t_hi - t_lo)
        text += f" of its travel {t_lo:.4g} to {t_hi:.4g} {unit} ({share:.0f} %)".replace("-", "−")
    return text


def tool_motion_um(fit_result, obs, *, setup: bool = False) -> float:
    """Largest displacement of the tool point, over the measured poses, that the identified errors cause, µm;
    without the set-up of the workpiece and the sensor (W, T) unless ``setup``."""
    from ..model import evaluate
    from ..fitting import design, joint_values

    machine = fit_result.machine
    d = design(machine, fit_result.effects, obs)
    values = joint_values(machine, d, fit_result.theta)
    if not setup:
        values[:, [j.axis in ("W", "T") for j in machine.error_joints]] = 0.0
    moved = evaluate(machine, obs.axes, values, jacobian=False)
    nominal = evaluate(machine, obs.axes, np.zeros(len(machine.error_joints)), jacobian=False)
    return float(np.max(np.linalg.norm(moved - nominal, axis=1)) * 1e3)


def _num(x: float) -> str:
    """A number for a sentence: 3 significant digits, no exponent below a million."""
    return f"{x:.3g}" if abs(x) < 100 else f"{x:,.0f}"


def _largest(fit_result, n=3) -> str:
    """The identified errors of largest size relative to their uncertainty, in words; not those of a size no
    machine has (flagged in the table: they are not clear, whatever their ratio)."""
    from ..model import axis_directions, plain_name

    axes = axis_directions(fit_result.machine)
    flagged = {a.effect for a in fit_result.implausible()}
    scored, k = [], 0
    for e in fit_result.effects:
        sl = slice(k, k + e.n_params)
        if e.code.endswith(("0W", "0T")) or e.name in flagged:  # the set-up of board and sensor: not the machine's
            k += e.n_params
            continue
        ok = np.asarray(fit_result.identifiable[sl], bool)
        if ok.any():
            v = np.asarray(fit_result.values[sl])[ok]
            sd = np.asarray(fit_result.std[sl])[ok]
            size = float(np.hypot.reduce(v)) if v.size > 1 else float(abs(v[0]))
            z = size / max(float(np.hypot.reduce(sd)), 1e-300)
            unit = fit_result.units[k].replace("um", "µm").replace("urad", "µrad").split("/")[0]
            scored.append((z, f"{plain_name(e.code, axes)} ({e.name}, {_num(size)} {unit})"))
        k += e.n_params
    scored.sort(reverse=True)
    clearest = "; ".join(t for z, t in scored[:n] if z > 3) or "no error stands out of its uncertainty"
    return clearest + ("; the sizes no machine has, flagged in the table, are left out" if flagged else "")


def _provenance(fit_result, obs, extra=()) -> list:
    import hashlib

    from kinid.reports.html import file_provenance, now_utc

    m = fit_result.machine
    urdf = hashlib.sha256(m.urdf.encode()).hexdigest()
    rows = [("machine", f"{Path(m.path).name} (URDF SHA-256 {urdf})")]
    if obs is not None and obs.source and not obs.source.startswith("<"):
        rows.append(("data", file_provenance(obs.source)))
    elif obs is not None:
        rows.append(("data", f"{obs.source} ({len(obs)} rows)"))
    rows += list(extra)
    rows += [("alignments", f"{fit_result.n_observations}" + (f" ({len(fit_result.set_aside)} set aside as gross "
                                                                f"errors)" if fit_result.set_aside else "")),
             ("noise σ used", f"{fit_result.noise_um:.3g} µm per coordinate ({fit_result.noise_source})")]
    if fit_result.shared_std:
        rows.append(("uncertainties also include", ", ".join(s.replace("_", " ") for s in sorted(fit_result.shared_std))
                     + " (shared by every alignment: type B, from the sensor file)"))
    rows += [("made", now_utc())]
    return rows


def _runnable(path, placeholder: str) -> str:
    """``path`` as a command typed where the user stands takes it: relative to the working folder when inside it,
    quoted for the shell; ``placeholder`` where there is no such file (a machine known only from a FIT.json)."""
    import os
    import shlex

    if not path or str(path).startswith("<") or not Path(path).is_file():
        return placeholder
    full = Path(path).resolve()
    try:
        shown = str(full.relative_to(Path.cwd().resolve()))
    except ValueError:
        shown = os.fspath(full)
    return shlex.quote(shown)


def _summary(diagnosis, obs, fit_file=None, selected: bool = False) -> list:
    """The summary's first two sentences: what the errors do, and what to do next (``selected``: the diagnosis is a
    selection's last, whose best candidate the selection did not add — it says why — so it is not advised)."""
    f = diagnosis.fit
    moved = tool_motion_um(f, obs)
    first = (f"The machine's identified errors (the board's and the sensor's set-up aside) move the tool point by "
             f"up to {_num(moved)} µm over the measured poses; the clearest (the largest against their "
             f"uncertainty): {_largest(f)}.")
    if diagnosis.verdict == "noise":
        second = (f"The model explains the data to the noise (residual {diagnosis.rms_um:.3g} µm per coordinate, "
                  f"σ {diagnosis.noise_um:.3g} µm){': ' + diagnosis.note if diagnosis.note else ''}; next: load the "
                  f"compensation (kinid compensate --fit {fit_file or 'FIT.json'} --out "
                  f"{'compensation' if fit_file else 'DIR'}).")
    else:
        best = diagnosis.advised[0]
        rms, sigma = f"{diagnosis.rms_um:.3g}", f"{diagnosis.noise_um:.3g}"
        if diagnosis.chi2_p < ALPHA:  # the residual as a whole exceeds the σ given
            lacks = f"The residual ({rms} µm per coordinate against σ {sigma} µm) shows an effect the model lacks"
        else:  # at the noise as a whole (or σ was estimated from it), but a part of it stands out from noise
            lacks = (f"The residual ({rms} µm per coordinate, near σ {sigma} µm) holds, beneath the noise, an effect "
                     f"the model lacks")
        if best is not None and best.p_value < diagnosis.threshold and selected:
            second = (f"{lacks}; its most likely cause, {best.effect}, was not added, for the reason above: measure "
                      f"more where it acts (kinid plan --detect {best.effect}=SIZE) and identify again.")
        elif best is not None and best.p_value < diagnosis.threshold:
            machine = _runnable(getattr(diagnosis.fit.machine, "path", None), "URDF")
            data = _runnable(getattr(obs, "source", None), "OBS.csv")
            noise = "" if diagnosis.noise_source == "residuals" else f" --noise-um {diagnosis.noise_um:.3g}"
            second = (f"{lacks}, most likely {best.effect} (p = {best.p_value:.2g}); next: kinid identify --machine "
                      f"{machine} --data {data} --add {best.effect}{noise} --out fit_added.json.")
        else:
            second = (f"The residual ({diagnosis.rms_um:.3g} µm per coordinate) exceeds the noise "
                      f"(σ {diagnosis.noise_um:.3g} µm) but no candidate explains it"
                      f"{': ' + diagnosis.note if diagnosis.note else ''}; look at the binned residuals "
                      f"below, or check the URDF for missing error joints.")
    return [first, second]


def diagnosis_report(diagnosis, obs, folder, *, provenance=()) -> Path:
    """Write the plots, ``residuals.csv`` and ``index.html`` of one diagnosis into ``folder``; returns the page's path.

    The folder is written whole or not at all, and replaces only an empty folder or an earlier report
    (:func:`kinid.reports.html.report_folder`; a DataError otherwise).
    """
    with report_folder(folder) as stage:
        _diagnosis_report(diagnosis, obs, stage, provenance)
    return Path(folder) / "index.html"


def _diagnosis_report(diagnosis, obs, folder: Path, provenance) -> Path:
    f = diagnosis.fit
    machine = f.machine
    figs = _figures("", machine, obs, f, folder, diagnosis)
    write_text(folder / "residuals.csv", residuals_csv(diagnosis, obs))
    if diagnosis.axis_names and np.all(np.isfinite(diagnosis.axis_residuals_um)):
        plot_measured_vs_model(diagnosis, obs, folder / "measured_vs_model.png")
        figs.append(Figure("measured_vs_model.png", "Measured minus model readings, alignment by alignment "
                                                    "(the numbers: residuals.csv)"))
    error_figs = []
    if plot_identified_errors(f, obs, folder / "errors.png"):
        error_figs.append(Figure("errors.png", "Identified position-dependent errors against their axes, with the "
                                               "±2σ band (k = 2)"))
    if plot_maps(f, folder / "maps.png"):
        error_figs.append(Figure("maps.png", "Identified error maps at their knots with the ±2σ band"))
    live = diagnosis.live[:10]
    cand = Table(("rank", "effect", "p-value", "RMS after (µm)", "estimated size", "U (k = 2)", "unit"),
                 tuple((str(i), c.effect, f"{c.p_value:.2g}", f"{c.rms_after_um:.3f}", f"{c.size:.4g}",
                        f"{2 * c.size_std:.2g}", c.size_unit.replace("um", "µm").replace("urad", "µrad"))
                       for i, c in enumerate(live, 1)), numeric=(0, 2, 3, 4, 5),
                 caption=f"Threshold for a missing effect: p < {diagnosis.threshold:.3g} (α = {ALPHA:g} over the "
                         f"{len(diagnosis.live)} candidates tested). Size: the amplitude of a periodic effect, the "
                         f"highest term of a polynomial, the peak of a map; U: expanded uncertainty, k = 2, as in the "
                         f"table of identified errors.")
    sections = [
        Section("Identified errors", tables=(errors_table(f, obs=obs),), figures=tuple(error_figs)),
        Section("Where the model fails", paragraphs=(f"Verdict: {diagnosis.verdict}. Residual {diagnosis.rms_um:.3f} µm "
                                                     f"per coordinate; σ {diagnosis.noise_um:.3f} µm ({diagnosis.noise_source}).",),
                tables=(cand,) if live else (), figures=tuple(figs), details=diagnosis.text(top=15) + "\n\n" + f.table()),
    ]
    page = folder / "index.html"
    write_report(folder, "Machine diagnosis", f"kinid diagnose: {Path(machine.path).name}",
                 _provenance(f, obs, provenance), _summary(diagnosis, obs), sections)
    return page


def selection_report(steps, obs, folder, *, held_out=None, provenance=(), whole: bool = True,
                     fit_file=None) -> Path:
    """Write the forward-selection report (falling error, first and last residual plots) into ``folder``;
    returns the page's path.

    Parameters
    ----------
    held_out : (str, sequence of float, str), optional
        A column of the step table: its header, each step's held-out error (µm) and, for the caption, how it
        was measured (the demo: the tool point's error at poses the fit did not see, against the truth).
        By default the blocks of the data the selection's held-out check left out (when it ran).
    whole : bool
        Write the folder whole or not at all, replacing only an empty folder or an earlier report
        (:func:`kinid.reports.html.report_folder`), or (False) write the report's files into ``folder``
        beside what it holds (the demo, whose page goes into its own output folder beside its data).
    fit_file : str, optional
        Where the final fit was written, as the next step's command should name it.
    """
    if not whole:
        return _selection_report(steps, obs, _outdir(folder), held_out, provenance, fit_file)
    with report_folder(folder) as stage:
        _selection_report(steps, obs, stage, held_out, provenance, fit_file)
    return Path(folder) / "index.html"


def _blocks_held_out(steps):
    """The selection's own held-out check as a column of the step table: the RMS of the blocks left out, before
    the first effect and after each one added; None if the check did not run before every step."""
    checks = [s.held_out for s in steps[:-1]]
    if not checks or any(c is None for c in checks):
        return None
    values = [checks[0].rms_without_um] + [c.rms_with_um for c in checks]
    return ("held-out RMS (µm)", values, f"residual RMS per coordinate of the blocks of the data left out of the fit "
                                         f"in turn ({checks[0].folds}-fold), the check each effect passed to be added")


def _selection_report(steps, obs, folder: Path, held_out, provenance, fit_file=None) -> Path:
    machine = steps[0].fit.machine
    if len(steps) > 1:
        plot_selection(steps, folder / "rms_steps.png")
    first = steps[0].data if getattr(steps[0], "data", None) is not None else obs  # gross errors set aside
    last = steps[-1].data if getattr(steps[-1], "data", None) is not None else obs
    final = steps[-1].fit
    header = ["step", "model", "residual RMS (µm)", "σ (µm)", "verdict"]
    rows = [[str(i), "default model" if i == 0 else f"+ {s.added}", f"{s.diagnosis.rms_um:.3f}",
             f"{s.diagnosis.noise_um:.3f}", s.diagnosis.verdict] for i, s in enumerate(steps)]
    caption = "Residual RMS per coordinate of each step's fit, against the noise σ it used."
    held_out = held_out or _blocks_held_out(steps)
    if held_out is not None:
        name, values, how = held_out
        header.insert(3, name)
        for row, v in zip(rows, values):
            row.insert(3, f"{v:.3f}")
        caption += f" Held-out: {how}."
    table = Table(tuple(header), tuple(map(tuple, rows)), numeric=tuple(range(2, len(header) - 1)) + (0,),
                  caption=caption)
    frames = FigureFrames()  # the first and the last fit's residual figures: the same panels, drawn twice
    error_figs = []
    if plot_identified_errors(final, last, folder / "errors.png"):
        error_figs.append(Figure("errors.png", "Identified position-dependent errors against their axes, with the "
                                               "±2σ band (k = 2)"))
    if plot_maps(final, folder / "maps.png"):
        error_figs.append(Figure("maps.png", "Identified error maps at their knots with the ±2σ band"))
    sections = [
        Section("The error falls as effects are added", tables=(table,),
                figures=(Figure("rms_steps.png", "Residual RMS per step against the noise σ"),))
        if len(steps) > 1 else Section("Nothing was added: the default model stays", tables=(table,)),
        Section("Identified errors (final model)", tables=(errors_table(final, obs=last),), figures=tuple(error_figs)),
        Section("Default model: " + ("its residual" if steps[0].diagnosis.verdict == "noise" else "where it fails"),
                figures=tuple(_figures("before_", machine, first, steps[0].fit, folder, steps[0].diagnosis, frames)),
                details=steps[0].diagnosis.text(top=10)),
    ]
    if len(steps) > 1:
        sections.append(Section("Final model: what is left", figures=tuple(_figures("after_", machine, last, final, folder,
                                                                                    steps[-1].diagnosis, frames)),
                                details=steps[-1].diagnosis.text(top=5) + "\n\n" + final.table()))
    write_text(folder / "residuals.csv", residuals_csv(steps[-1].diagnosis, last))
    page = folder / "index.html"
    from ..diagnosis import what_is_left

    summary = _summary(steps[-1].diagnosis, last, fit_file, selected=True)
    left = what_is_left(steps)
    summary.insert(1, left[0].upper() + left[1:] + ".")
    write_report(folder, "Machine calibration: compare, diagnose, add", f"kinid: {Path(machine.path).name}",
                 _provenance(final, last, provenance), summary, sections)
    return page
