"""The verification report: the error before and after the compensation, and what is left."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from kinid.reports.figures import new_figure, save_figure
from kinid.reports.html import Figure, Section, Table, file_provenance, now_utc, report_folder, write_report

__all__ = ["verification_report", "plot_before_after"]


def plot_before_after(v, path) -> None:
    """Grouped bars: RMS before and after per coordinate and 3-D, with the level noise alone leaves."""
    keys, labels = ("x", "y", "z", "3d"), ("x", "y", "z", "3-D")
    fig = new_figure((6.4, 3.4))
    ax = fig.subplots()
    pos = np.arange(len(keys))
    before = [v.before_um[k] for k in keys]
    after = [v.after_um[k] for k in keys]
    ax.bar(pos - 0.2, before, 0.4, color="#b0b7bf", label="before")
    ax.bar(pos + 0.2, after, 0.4, color="#2f6fbf", label="after")
    per_coordinate = v.noise_level_3d_um / np.sqrt(3.0)
    for p, level in zip(pos, (per_coordinate,) * 3 + (v.noise_level_3d_um,)):
        ax.hlines(level, p - 0.45, p + 0.45, color="#c0392b", lw=1.4, ls="--",
                  label="what the noise alone leaves" if p == 0 else None)
    ax.set_xticks(pos, [f"{lab}" for lab in labels])
    ax.set_ylabel("tool point error, RMS (µm)")
    ax.set_ylim(0, 1.15 * max(before + after))
    ax.legend(fontsize=9, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    for p, b, a in zip(pos, before, after):
        ax.annotate(f"{b:.3g}", (p - 0.2, b), ha="center", va="bottom", fontsize=8)
        ax.annotate(f"{a:.3g}", (p + 0.2, a), ha="center", va="bottom", fontsize=8)
    save_figure(fig, path)


def verification_report(v, folder, *, fit_path, data_path) -> Path:
    """Write ``index.html`` and its figure into ``folder``; returns the page's path.

    The folder is written whole or not at all, and replaces only an empty folder or an earlier report
    (:func:`kinid.reports.html.report_folder`; a DataError otherwise).
    """
    with report_folder(folder) as stage:
        _verification_report(v, stage, fit_path=fit_path, data_path=data_path)
    return Path(folder) / "index.html"


def _verification_report(v, folder: Path, *, fit_path, data_path) -> None:
    from kinid.files import write_json

    write_json(folder / "verify.json", v.summary())  # what kinid verify --json prints, for kinid certificate
    plot_before_after(v, folder / "before_after.png")
    rows = tuple((name, *(f"{d[k]:.3f}" for k in ("x", "y", "z", "3d")))
                 for name, d in ((f"before ({v.before_source})", v.before_um),
                                 ("after (this run, set-up refitted)", v.after_um)))
    table = Table(("", "x (µm)", "y (µm)", "z (µm)", "3-D (µm)"), rows, numeric=(1, 2, 3, 4),
                  caption="RMS of the tool point error in the workpiece frame over the run's alignments")
    if v.at_noise_level:
        summary = [f"The compensation worked: the tool point error fell from {v.before_um['3d']:.3g} µm to "
                   f"{v.after_um['3d']:.3g} µm 3-D RMS, the level the measurement noise alone leaves "
                   f"({v.noise_level_3d_um:.3g} µm).",
                   "Nothing to do; measure again when the machine has been moved, repaired or after a season."]
    elif v.made_worse:
        summary = [f"Made worse: the tool point error grew from {v.before_um['3d']:.3g} µm to "
                   f"{v.after_um['3d']:.3g} µm 3-D RMS" + (f"; {v.where_words}." if v.where_words else "."),
                   "Unload the compensation and check its ranges and signs (compensation.json) and that it was made "
                   "from this machine's fit."]
    else:
        best = v.diagnosis.advised[0]
        summary = [f"Error remains: {v.after_um['3d']:.3g} µm 3-D RMS against {v.noise_level_3d_um:.3g} µm from "
                   f"noise (it was {v.before_um['3d']:.3g} µm before).",
                   (f"What remains looks like {best.effect}: identify it on this run and compensate again."
                    if best is not None and best.p_value < v.diagnosis.threshold else
                    "No effect of the library explains it: check the set-up, the sensor offsets and the σ given.")]
    sections = [Section("Before and after", tables=(table,), figures=(Figure(
        "before_after.png", "Tool point error before and after the compensation, RMS per coordinate and 3-D, "
                            "and the level the measurement noise alone leaves"),),
        paragraphs=(f"σ {v.noise.value_um:.3g} µm per coordinate ({v.noise_words})"
                    + (f"; {v.test} of what is left against σ: p = {v.chi2_p:.3g}." if np.isfinite(v.chi2_p)
                       else "."),)),
        Section("What remains", paragraphs=(f"Verdict of the diagnosis of the remaining error: "
                                            f"{v.diagnosis.verdict}.",),
                details=v.diagnosis.text(top=10))]
    write_report(folder, "Compensation check", "kinid verify: the run after loading the compensation",
                 [("fit", file_provenance(fit_path)), ("second run", file_provenance(data_path)),
                  ("alignments", str(v.n_observations)), ("date", now_utc())],
                 summary, sections)
