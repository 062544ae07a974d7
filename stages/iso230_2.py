"""ISO 230-2 evaluation of bidirectional positioning runs of one axis, and the ``kinid iso230-2`` command.

Input (RUNS.csv): one row per measurement, columns ``target_mm`` (target
position P_i), ``run`` (run number j), ``direction`` (+1 approaching in the
positive direction ↑, −1 in the negative ↓) and ``deviation_um`` (positional
deviation x_ij = measured − target, µm). Every target needs at least two runs
in each direction.

The values follow ISO 230-2 (test code for machine tools — determination of
accuracy and repeatability of positioning of numerically controlled axes),
for m targets and n runs per direction:

- mean unidirectional positional deviation  x̄_i↑ = Σ_j x_ij↑ / n  (likewise ↓)
- mean bidirectional positional deviation   x̄_i = (x̄_i↑ + x̄_i↓) / 2
- reversal value at a position              B_i = x̄_i↑ − x̄_i↓
- reversal value of the axis                B = max |B_i|;  mean reversal value B̄ = Σ_i B_i / m
- standard uncertainty (estimator)          s_i↑ = √(Σ_j (x_ij↑ − x̄_i↑)² / (n − 1))  (likewise ↓)
- unidirectional repeatability              R_i↑ = 4 s_i↑;  R↑ = max R_i↑  (likewise ↓)
- bidirectional repeatability               R_i = max(2 s_i↑ + 2 s_i↓ + |B_i|, R_i↑, R_i↓);  R = max R_i
- unidirectional systematic deviation       E↑ = max x̄_i↑ − min x̄_i↑  (likewise ↓)
- bidirectional systematic deviation        E = max(x̄_i↑, x̄_i↓) − min(x̄_i↑, x̄_i↓)
- range of mean bidirectional deviation     M = max x̄_i − min x̄_i
- unidirectional accuracy                   A↑ = max(x̄_i↑ + 2 s_i↑) − min(x̄_i↑ − 2 s_i↑)  (likewise ↓)
- bidirectional accuracy                    A = max(x̄_i↑ + 2 s_i↑, x̄_i↓ + 2 s_i↓) − min(x̄_i↑ − 2 s_i↑, x̄_i↓ − 2 s_i↓)
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from kinid.errors import DataError
from kinid.options import add_positional_alias

if TYPE_CHECKING:  # numpy is imported by the functions that compute: ``kinid iso230-2 --help`` loads without it
    import numpy as np

__all__ = ["PositioningResult", "evaluate_runs", "read_runs", "register", "STANDARD"]

_COLUMNS = ("target_mm", "run", "direction", "deviation_um")
#: The edition the values follow.
STANDARD = "ISO 230-2:2014"


def _decimals(values_um) -> int:
    """Decimals that give the largest of ``values_um`` four significant digits (1 to 5): 22.04, 5.123, 0.08941."""
    import math

    big = max((abs(float(v)) for v in values_um), default=0.0)
    return 3 if big == 0 else min(5, max(1, 3 - math.floor(math.log10(big))))


@dataclass(frozen=True)
class PositioningResult:
    """ISO 230-2 values of one axis (µm); per-position arrays in target order.

    Attributes
    ----------
    targets_mm : array (m,)
    mean_up_um, mean_down_um, mean_um : array (m,)
        x̄_i↑, x̄_i↓ and x̄_i.
    s_up_um, s_down_um : array (m,)
        s_i↑, s_i↓.
    reversal_um : array (m,)
        B_i.
    repeatability_um : array (m,)
        R_i.
    A_um, A_up_um, A_down_um, E_um, E_up_um, E_down_um, R_um, R_up_um, R_down_um, M_um, B_um, mean_reversal_um : float
    runs : int
        Runs per direction (n, the smallest over the targets).
    """

    targets_mm: np.ndarray
    mean_up_um: np.ndarray
    mean_down_um: np.ndarray
    mean_um: np.ndarray
    s_up_um: np.ndarray
    s_down_um: np.ndarray
    reversal_um: np.ndarray
    repeatability_um: np.ndarray
    A_um: float
    A_up_um: float
    A_down_um: float
    E_um: float
    E_up_um: float
    E_down_um: float
    R_um: float
    R_up_um: float
    R_down_um: float
    M_um: float
    B_um: float
    mean_reversal_um: float
    runs: int

    def summary(self) -> dict:
        """The ``--json`` object: every axis value and the per-position table."""
        keys = ("A_um", "A_up_um", "A_down_um", "E_um", "E_up_um", "E_down_um", "R_um", "R_up_um", "R_down_um",
                "M_um", "B_um", "mean_reversal_um")
        out = {k: float(getattr(self, k)) for k in keys}
        out["runs"] = self.runs
        out["positions"] = [
            {"target_mm": float(t), "mean_up_um": float(u), "mean_down_um": float(d), "mean_um": float(x),
             "s_up_um": float(su), "s_down_um": float(sd), "reversal_um": float(b), "repeatability_um": float(r)}
            for t, u, d, x, su, sd, b, r in zip(self.targets_mm, self.mean_up_um, self.mean_down_um, self.mean_um,
                                               self.s_up_um, self.s_down_um, self.reversal_um, self.repeatability_um)]
        return out

    def text(self, axis: str = "", source: str = "") -> str:
        """The report as text: the standard's edition, the axis and file, then the table and the values, in µm
        with decimals enough for four significant digits of the accuracy A."""
        k = _decimals([self.A_um, self.R_um, self.E_um])
        w = 9 + max(k - 3, 0)
        named = f" of axis {axis}" if axis else " of one axis"
        lines = [f"{STANDARD} positioning{named}" + (f" from {source}" if source else "")
                 + f": {len(self.targets_mm)} targets, {self.runs} runs per direction",
                 "", f"{'target (mm)':>12} {'x̄↑ (µm)':>{w}} {'x̄↓ (µm)':>{w}} {'B_i (µm)':>{w}} {'s↑ (µm)':>{w}} "
                     f"{'s↓ (µm)':>{w}} {'R_i (µm)':>{w}}"]
        for t, u, d, b, su, sd, r in zip(self.targets_mm, self.mean_up_um, self.mean_down_um, self.reversal_um,
                                         self.s_up_um, self.s_down_um, self.repeatability_um):
            lines.append(f"{t:12.3f} {u:{w}.{k}f} {d:{w}.{k}f} {b:{w}.{k}f} {su:{w}.{k}f} {sd:{w}.{k}f} {r:{w}.{k}f}")
        lines += ["", f"{'':<44}{'bidirectional':>14}{'↑':>{w}}{'↓':>{w}}",
                  f"{'accuracy A (µm)':<44}{self.A_um:14.{k}f}{self.A_up_um:{w}.{k}f}{self.A_down_um:{w}.{k}f}",
                  f"{'systematic positional deviation E (µm)':<44}{self.E_um:14.{k}f}{self.E_up_um:{w}.{k}f}"
                  f"{self.E_down_um:{w}.{k}f}",
                  f"{'repeatability R (µm)':<44}{self.R_um:14.{k}f}{self.R_up_um:{w}.{k}f}{self.R_down_um:{w}.{k}f}",
                  f"{'range of mean bidirectional deviation M (µm)':<44}{self.M_um:14.{k}f}",
                  f"{'reversal value B (µm)':<44}{self.B_um:14.{k}f}",
                  f"{'mean reversal value B̄ (µm)':<44}{self.mean_reversal_um:14.{k}f}"]
        return "\n".join(lines)


def evaluate_runs(target_mm, direction, deviation_um) -> PositioningResult:
    """ISO 230-2 values from measurements (one entry each): target, direction ±1, deviation µm.

    Raises
    ------
    DataError
        A direction other than ±1, a non-finite value, or a target with fewer
        than two runs in a direction.
    """
    import numpy as np

    t = np.asarray(target_mm, dtype=float)
    d = np.asarray(direction, dtype=float)
    x = np.asarray(deviation_um, dtype=float)
    if not (t.shape == d.shape == x.shape and t.ndim == 1 and t.size):
        raise DataError("target_mm, direction and deviation_um must be 1-D arrays of one length", parameter="runs")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(x))):
        raise DataError("must be finite", parameter="target_mm and deviation_um")
    if not np.all(np.isin(d, (-1.0, 1.0))):
        raise DataError("must be +1 or -1", parameter="direction")
    targets = np.unique(t)
    stats = {}
    for sign in (1.0, -1.0):
        means, stds, counts = [], [], []
        for p in targets:
            v = x[(t == p) & (d == sign)]
            if v.size < 2:
                arrow = "+" if sign > 0 else "-"
                raise DataError(f"target {p:g} mm has {v.size} run(s) in direction {arrow}; ISO 230-2 needs at "
                                f"least 2 (it recommends 5)", parameter="runs")
            means.append(v.mean())
            stds.append(v.std(ddof=1))
            counts.append(v.size)
        stats[sign] = (np.array(means), np.array(stds), min(counts))
    up, s_up, n_up = stats[1.0]
    down, s_down, n_down = stats[-1.0]
    mean = (up + down) / 2
    rev = up - down
    r_up, r_down = 4 * s_up, 4 * s_down
    r_bi = np.maximum.reduce([2 * s_up + 2 * s_down + np.abs(rev), r_up, r_down])
    both = np.r_[up, down]
    return PositioningResult(
        targets_mm=targets, mean_up_um=up, mean_down_um=down, mean_um=mean, s_up_um=s_up, s_down_um=s_down,
        reversal_um=rev, repeatability_um=r_bi,
        A_um=float(max(np.max(up + 2 * s_up), np.max(down + 2 * s_down))
                   - min(np.min(up - 2 * s_up), np.min(down - 2 * s_down))),
        A_up_um=float(np.max(up + 2 * s_up) - np.min(up - 2 * s_up)),
        A_down_um=float(np.max(down + 2 * s_down) - np.min(down - 2 * s_down)),
        E_um=float(both.max() - both.min()), E_up_um=float(np.ptp(up)), E_down_um=float(np.ptp(down)),
        R_um=float(r_bi.max()), R_up_um=float(r_up.max()), R_down_um=float(r_down.max()),
        M_um=float(np.ptp(mean)), B_um=float(np.max(np.abs(rev))), mean_reversal_um=float(rev.mean()),
        runs=int(min(n_up, n_down)))


#: The largest deviation from a target a run may hold, µm (1 m: beyond any axis's positioning error).
MAX_DEVIATION_UM = 1e6


def read_runs(path):
    """(target_mm, direction, deviation_um) arrays from RUNS.csv; DataError naming the line and column."""
    import numpy as np

    from kinid.files import csv_number, read_csv_rows

    rows = read_csv_rows(path, what="runs file")
    if not rows:
        raise DataError(f"empty; expected a header {','.join(_COLUMNS)} and rows", path=path)
    header_line, header = rows[0]
    header = [h.strip() for h in header]
    for col in _COLUMNS:
        if col not in header:
            raise DataError(f"missing column {col!r} (header: {', '.join(header)})", path=path, line=header_line)
    idx = [header.index(c) for c in _COLUMNS]
    out = []
    seen = {}
    for lineno, cells in rows[1:]:
        values = [csv_number(cells, i, path=path, line=lineno, column=col) for col, i in zip(_COLUMNS, idx)]
        if values[2] not in (1.0, -1.0):
            raise DataError(f"direction must be +1 or -1, found {cells[idx[2]].strip()!r}", path=path, line=lineno,
                            column="direction")
        if not abs(values[3]) <= MAX_DEVIATION_UM:  # 1e155 squared to infinity: the results were null
            raise DataError(f"a deviation of {values[3]:g} µm is beyond {MAX_DEVIATION_UM:g} µm (1 m): a deviation is "
                            f"in µm from the target", path=path, line=lineno, column="deviation_um")
        key = tuple(values[:3])
        if key in seen:
            raise DataError(f"target {values[0]:g} mm, run {values[1]:g}, direction {values[2]:+g} is measured twice, "
                            f"on lines {seen[key]} and {lineno}: keep one (a repeated run needs its own run number)",
                            path=path, line=lineno)
        seen[key] = lineno
        out.append(values)
    if not out:
        raise DataError("no measurements after the header", path=path, line=header_line)
    a = np.array(out)
    _warn_if_mm(path, a[:, 3])
    return a[:, 0], a[:, 2], a[:, 3]


#: Deviations all below this (µm) while they vary look like millimetres written under ``deviation_um``.
LOOKS_LIKE_MM_UM = 0.05


def _warn_if_mm(path, deviation_um) -> None:
    """A warning when every deviation is a few hundredths of a µm yet they scatter: millimetres in a µm column
    (a real axis deviates by tenths of a µm and more; a laser interferometer's noise alone is ~0.01 µm)."""
    import warnings

    import numpy as np

    d = np.abs(deviation_um)
    if d.max() < LOOKS_LIKE_MM_UM and np.ptp(deviation_um) > 0:
        warnings.warn(f"{path}: every deviation_um is below {LOOKS_LIKE_MM_UM} µm (largest {d.max():.3g}); if they "
                      f"are millimetres, multiply by 1000", stacklevel=3)


def plot_runs(result: PositioningResult, path, *, axis: str = "", source: str = "") -> None:
    """The standard's plot: mean deviation per direction with ±2s bands against the target; the legend below the
    axes (never over the points), the edition, axis and file in the title."""
    from kinid.reports.figures import new_figure, save_figure

    fig = new_figure((7.5, 4.2))
    ax = fig.subplots()
    t = result.targets_mm
    for mean, s, colour, label in ((result.mean_up_um, result.s_up_um, "tab:red", "↑ (positive approach)"),
                                   (result.mean_down_um, result.s_down_um, "tab:blue", "↓ (negative approach)")):
        ax.plot(t, mean, "o-", color=colour, label=f"mean deviation {label}")
        ax.plot(t, mean + 2 * s, "--", color=colour, lw=0.9)
        ax.plot(t, mean - 2 * s, "--", color=colour, lw=0.9, label=f"±2s {label.split()[0]}")
    ax.plot(t, result.mean_um, "k:", lw=1.0, label="mean bidirectional deviation")
    ax.axhline(0, color="0.6", lw=0.8)
    ax.set_xlabel("target position (mm)")
    ax.set_ylabel("positional deviation (µm)")
    k = _decimals([result.A_um, result.R_um, result.E_um])
    named = f"axis {axis}" if axis else "one axis"
    ax.set_title(f"{STANDARD}, {named}" + (f" ({source})" if source else "") +
                 f"\nA = {result.A_um:.{k}f} µm, E = {result.E_um:.{k}f} µm, R = {result.R_um:.{k}f} µm, "
                 f"B = {result.B_um:.{k}f} µm", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=3, frameon=False)
    save_figure(fig, path)


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "iso230-2", help="ISO 230-2 accuracy, repeatability and reversal of one axis from bidirectional runs",
        description="Evaluate bidirectional positioning runs of one axis by ISO 230-2: A, E, R, M, B, the mean "
                    "reversal value and the unidirectional values. RUNS.csv columns: "
                    "target_mm,run,direction,deviation_um (direction +1/-1; deviation = measured - target, µm).")
    p.add_argument("--data", dest="runs", metavar="RUNS.csv", help="bidirectional positioning runs (required)")
    p.add_argument("--json", action="store_true", help="print one JSON object (keys A_um, E_um, R_um, M_um, B_um, ...)")
    p.add_argument("--plot", metavar="OUT.png", help="mean deviations ±2s per direction against the target")
    p.add_argument("--axis", default="", metavar="NAME", help="the axis measured, for the report (e.g. X)")
    p.add_argument("--report", metavar="DIR", help="write the test report into DIR: the standard's values, the "
                                                   "table per target, the plot (HTML, one-file HTML and PDF)")
    add_positional_alias(p, "RUNS.csv", "--data")
    p.set_defaults(run=_run, outputs={"plot": "file", "report": "replaced folder"})


def _run(args) -> int:
    if args.runs is None:
        raise DataError("no runs given: --data RUNS.csv (target_mm,run,direction,deviation_um)")
    target, direction, deviation = read_runs(args.runs)
    try:
        result = evaluate_runs(target, direction, deviation)
    except DataError as exc:
        raise DataError(str(exc), path=args.runs) from None
    from pathlib import Path

    from kinid.untrusted import shown_path

    source = shown_path(Path(args.runs).name)
    axis = shown_path(args.axis) if args.axis else ""
    if args.report:
        from kinid.reports.html import check_report_folder

        check_report_folder(args.report)
    if args.plot:
        plot_runs(result, args.plot, axis=axis, source=source)
    if args.report:
        from .outputs import staged_report

        with staged_report(args) as staged:
            write_report(result, staged.report, args.runs, axis=axis, source=source)
    from kinid.files import strict_json

    summary = {"standard": STANDARD, "axis": args.axis, "source": str(args.runs), **result.summary()}
    print(strict_json(summary) if args.json else result.text(axis, source))
    if args.report and not args.json:
        print(f"report written to {args.report}")
    return 0


def write_report(result: PositioningResult, folder, runs_path, *, axis: str = "", source: str = "") -> None:
    """The test report (kinid.reports.html): the provenance, the axis values of the standard in a table, the values
    per target, the plot, and the text output."""
    from pathlib import Path

    from kinid.reports.html import Figure, Section, Table, file_provenance, now_utc
    from kinid.reports.html import write_report as write_pages

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    plot_runs(result, folder / "positioning.png", axis=axis, source=source)
    k = _decimals([result.A_um, result.R_um, result.E_um])
    named = f"axis {axis}" if axis else "the axis"
    values = Table(("value", "bidirectional (µm)", "↑ (µm)", "↓ (µm)"), (
        ("accuracy A", f"{result.A_um:.{k}f}", f"{result.A_up_um:.{k}f}", f"{result.A_down_um:.{k}f}"),
        ("systematic positional deviation E", f"{result.E_um:.{k}f}", f"{result.E_up_um:.{k}f}",
         f"{result.E_down_um:.{k}f}"),
        ("repeatability R", f"{result.R_um:.{k}f}", f"{result.R_up_um:.{k}f}", f"{result.R_down_um:.{k}f}"),
        ("range of mean bidirectional deviation M", f"{result.M_um:.{k}f}", "—", "—"),
        ("reversal value B", f"{result.B_um:.{k}f}", "—", "—"),
        ("mean reversal value B̄", f"{result.mean_reversal_um:.{k}f}", "—", "—")), numeric=(1, 2, 3),
        caption=f"{STANDARD}: ↑ positive approach, ↓ negative; A and R include ±2s (s the estimator of the standard "
                f"uncertainty at each target from {result.runs} runs per direction); — the standard defines none.")
    rows = tuple((f"{t:.3f}", f"{u:.{k}f}", f"{d:.{k}f}", f"{b:.{k}f}", f"{su:.{k}f}", f"{sd:.{k}f}", f"{r:.{k}f}")
                 for t, u, d, b, su, sd, r in zip(result.targets_mm, result.mean_up_um, result.mean_down_um,
                                                  result.reversal_um, result.s_up_um, result.s_down_um,
                                                  result.repeatability_um))
    targets = Table(("target (mm)", "mean ↑ (µm)", "mean ↓ (µm)", "reversal B_i (µm)", "s ↑ (µm)", "s ↓ (µm)",
                     "repeatability R_i (µm)"), rows, numeric=tuple(range(7)),
                    caption="Per target: the mean unidirectional positional deviations, their difference B_i, the "
                            "estimators s of the standard uncertainty, and the bidirectional repeatability R_i.")
    span = f"{float(result.targets_mm.min()):g} to {float(result.targets_mm.max()):g} mm"
    summary = [f"Over {span} ({len(result.targets_mm)} targets, {result.runs} runs per direction) {named} positions "
               f"with accuracy A = {result.A_um:.{k}f} µm, repeatability R = {result.R_um:.{k}f} µm and reversal "
               f"value B = {result.B_um:.{k}f} µm ({STANDARD}).",
               "Compare with the machine's specification; where A is mostly systematic (E close to A), a pitch "
               "compensation table of the axis removes most of it (kinid compensate)."]
    prov = [("standard", f"{STANDARD} (determination of accuracy and repeatability of positioning of numerically "
                         f"controlled axes)"),
            ("axis", axis or "not named (--axis NAME)"), ("runs", file_provenance(runs_path)), ("made", now_utc())]
    sections = [Section("Values of the axis", tables=(values,)),
                Section("Per target", tables=(targets,), figures=(Figure(
                    "positioning.png", "Mean positional deviation per direction with ±2s bands, and the mean "
                                       "bidirectional deviation, against the target position"),)),
                Section("Text output", details=result.text(axis, source))]
    write_pages(folder, f"Positioning accuracy and repeatability of {named}", "kinid iso230-2", prov, summary,
                sections)
