"""The certificate a customer signs: one A4 page, PDF and HTML, from a fit, a verification and ISO 230-2 results.

:func:`build_certificate` gathers the content — the identification of the machine and the instrument, the conditions of
the measurement, the results in plain words and in small tables, the uncertainty statement (what kinid really
computes), the traceability line and the signature lines — from whichever of the three results is given;
:func:`write_certificate` writes ``certificate.pdf`` (:mod:`.certificate_layout`) and ``certificate.html`` (the
template ``kinid/templates/certificate.html``) into a folder, whole or not at all. Content that would not fit one
page is shrunk down to :data:`MIN_SCALE` and refused beyond; tables keep at most :data:`MAX_ERROR_ROWS` errors
(the largest against their uncertainty), saying how many more FIT.json holds.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

from kinid.errors import DataError
from kinid.stats import K_EXPANDED
from kinid.schema import Fields, Flag, Items, Number, Text, validate

from ..fitting import load_trusted_fit
from .certificate_layout import MIN_SCALE, Certificate, CertTable
from .certificate_meta import CertificateMeta

__all__ = ["Certificate", "CertTable", "build_certificate", "write_certificate", "read_verify", "read_iso",
           "MAX_ERROR_ROWS", "MIN_SCALE", "FILES"]

#: At most this many geometric errors in the table (the largest |value|/U first); the rest are counted.
MAX_ERROR_ROWS = 14
#: The files the certificate folder holds.
FILES = ("certificate.pdf", "certificate.html")

_RMS = Fields({"x": Number(low=0), "y": Number(low=0), "z": Number(low=0), "3d": Number(low=0)}, other=True)
#: What the certificate reads of ``kinid verify --json`` (or the verify.json of its report folder).
VERIFY_SCHEMA = Fields({"n_observations": Number(low=0, integer=True), "before_um": _RMS, "after_um": _RMS,
                        "before_source": Text(), "at_noise_level": Flag(), "made_worse": Flag(),
                        "noise_um": Number(low=0, null=True), "noise_level_3d_um": Number(low=0, null=True)},
                       optional={"before_max_3d_um": Number(low=0, null=True),
                                 "after_max_3d_um": Number(low=0, null=True)}, other=True)
_POSITION = Fields({"target_mm": Number()}, other=True)
#: What the certificate reads of ``kinid iso230-2 --json``.
ISO_SCHEMA = Fields({"standard": Text(), "A_um": Number(low=0), "R_um": Number(low=0), "E_um": Number(low=0),
                     "B_um": Number(low=0), "M_um": Number(low=0), "runs": Number(low=1, integer=True),
                     "positions": Items(_POSITION, min_length=1)}, optional={"axis": Text()}, other=True)


def _sha256(path) -> str:
    from kinid.files import MAX_JSON_BYTES, read_untrusted_bytes

    return hashlib.sha256(read_untrusted_bytes(path, what="input file", max_bytes=MAX_JSON_BYTES)).hexdigest()


def read_verify(path) -> dict:
    """``kinid verify --json``'s object from a file, or from the ``verify.json`` of a verify report folder."""
    from kinid.files import read_json

    p = Path(path)
    if p.is_dir():
        p = p / "verify.json"
        if not p.is_file():
            raise DataError("holds no verify.json: give the file `kinid verify --json > verify.json` writes, or "
                            "the folder of `kinid verify --report DIR`", path=path)
    return validate(read_json(p, what="verify result"), VERIFY_SCHEMA, path=p)


def read_iso(path) -> dict:
    """``kinid iso230-2 --json``'s object of one axis."""
    from kinid.files import read_json

    return validate(read_json(path, what="ISO 230-2 result"), ISO_SCHEMA, path=path)


def _g(x: float, digits: int = 3) -> str:
    """A value in µm to ``digits`` significant digits, never in exponent form (0.0123, 1.23, 12.3, 123)."""
    import math

    if x == 0 or not math.isfinite(x):
        return "0" if x == 0 else "—"
    decimals = max(0, digits - 1 - math.floor(math.log10(abs(x))))
    return f"{x:.{decimals}f}"


def build_certificate(meta: CertificateMeta, *, fit_path=None, verify_path=None, iso_paths=(), issued: str) -> Certificate:
    """The certificate's content from META.json's values and the results given (at least one of them).

    Parameters
    ----------
    meta : CertificateMeta
        :func:`.certificate_meta.read_meta`.
    fit_path, verify_path : path, optional
        FIT.json; ``kinid verify --json``'s file or report folder.
    iso_paths : sequence of path
        ``kinid iso230-2 --json`` files, one per axis.
    issued : str
        The date of issue (YYYY-MM-DD).
    """
    from kinid import __version__

    if fit_path is None and verify_path is None and not iso_paths:
        raise DataError("nothing to certify: give --fit FIT.json, --verify VERIFY.json or --iso ISO.json (one at least)")
    results, tables, uncertainty, trace = [], [], [], []
    fit = load_trusted_fit(fit_path) if fit_path is not None else None
    warnings = list(meta.warnings)
    if iso_paths:
        isos = [(p, read_iso(p)) for p in iso_paths]
        if fit is not None:
            warnings += _other_axes(isos, fit.machine)
        r, t, u = _iso_part(isos)
        results += r
        tables.append(t)
        uncertainty.append(u)
        trace += [(f"ISO 230-2 {d.get('axis') or Path(p).name}", f"{Path(p).name} SHA-256 {_sha256(p)}")
                  for p, d in isos]
    if verify_path is not None:
        v = read_verify(verify_path)
        if fit is not None:
            _same_machine(v, verify_path, fit, fit_path)
        r, t, u = _verify_part(v)
        results += r
        tables.append(t)
        uncertainty.append(u)
        vfile = Path(verify_path) / "verify.json" if Path(verify_path).is_dir() else Path(verify_path)
        trace.append(("verification", f"{vfile.name} SHA-256 {_sha256(vfile)}"))
    if fit is not None:
        r, t, u = _fit_part(fit)
        results += r
        tables.append(t)
        uncertainty.append(u)
        trace.insert(0, ("fit", f"{Path(fit_path).name} SHA-256 {_sha256(fit_path)}"))
    uncertainty.insert(0, f"The expanded uncertainties U are the standard uncertainties multiplied by the coverage "
                          f"factor k = {K_EXPANDED:g}, which for a normal distribution gives a coverage probability of "
                          f"about 95 % (GUM, JCGM 100:2008).")
    uncertainty.append("Not included: the uncertainty of the instrument's own calibration, and thermal effects "
                       "other than those present during the measurement.")
    trace.append(("software", f"kinid {__version__}"))
    m = meta.values
    identification = (("Machine", m["machine"]), ("Serial number", m["serial_number"]), ("Customer", m["customer"]),
                      ("Place", m.get("place", "—")), ("Operator", m["operator"]))
    conditions = (("Date of measurement", m["measurement_date"]),
                  ("Instrument", f"{m['instrument']}, serial {m['instrument_serial']}"),
                  ("Instrument calibrated", m["instrument_calibration_date"] + (
                      f" (certificate {m['instrument_calibration_certificate']})"
                      if m.get("instrument_calibration_certificate") else "")),
                  ("Temperature", f"machine {m['machine_temperature_c']:.1f} °C, air {m['air_temperature_c']:.1f} °C "
                                  f"(reference 20 °C, ISO 1)"),
                  ("Date of issue", issued))
    if m.get("remarks"):
        results.append(f"Remark: {m['remarks']}")
    return Certificate(title="Calibration certificate: geometric accuracy",
                       number=m.get("certificate_number", ""), identification=identification, conditions=conditions,
                       results=tuple(results), tables=tuple(tables), uncertainty=tuple(uncertainty),
                       traceability=tuple(trace), warnings=tuple(warnings), issued_by=m.get("issued_by", ""))


def _same_machine(v: dict, verify_path, fit, fit_path) -> None:
    """Refuses a verification made with another machine's fit than ``fit`` (``kinid verify`` records the SHA-256 of
    its machine's URDF); one made by a kinid that did not record it cannot be checked, and is warned about."""
    import warnings

    recorded = v.get("machine_sha256")
    if recorded is None:
        warnings.warn(f"{verify_path}: does not record its machine (made by an earlier kinid): that it verifies the "
                      f"machine of {Path(fit_path).name} is not checked", stacklevel=3)
    elif recorded != fit.machine.urdf_sha256:
        raise DataError(f"was made with another machine than {Path(fit_path).name}'s ({fit.machine.path}): its "
                        f"machine's URDF has SHA-256 {recorded[:12]}…, the fit's {fit.machine.urdf_sha256[:12]}…; "
                        f"give the verification of this fit's compensation", path=verify_path)


def _other_axes(isos, machine) -> list:
    """A sentence for the page per ISO 230-2 result whose axis is none of the fit's machine's axes."""
    out = []
    for path, d in isos:
        axis = d.get("axis")
        if axis and axis not in machine.axis_names:
            out.append(f"The ISO 230-2 result {Path(path).name} is of an axis {axis}, which the fitted machine does "
                       f"not have (its axes: {', '.join(machine.axis_names)}): check that it is of this machine.")
    return out


def _iso_part(isos):
    rows, words = [], []
    for path, d in isos:
        axis = d.get("axis") or Path(path).stem
        targets = [p["target_mm"] for p in d["positions"]]
        span = f"{min(targets):g} to {max(targets):g}"
        rows.append((axis, span, str(len(targets)), str(d["runs"]), _g(d["A_um"]), _g(d["R_um"]), _g(d["E_um"]),
                     _g(d["B_um"]), _g(d["M_um"])))
        words.append(f"Axis {axis} positions with accuracy A = {_g(d['A_um'])} µm and repeatability R = "
                     f"{_g(d['R_um'])} µm over {span} mm ({d['standard']}, {len(targets)} targets, {d['runs']} runs "
                     f"each way).")
    if len(isos) > 3:  # one sentence for many axes: the table carries each
        worst = max(isos, key=lambda pd: pd[1]["A_um"])
        words = [f"Positioning of {len(isos)} axes ({isos[0][1]['standard']}): accuracy A from "
                 f"{_g(min(d['A_um'] for _, d in isos))} to {_g(worst[1]['A_um'])} µm (axis "
                 f"{worst[1].get('axis') or Path(worst[0]).stem}), repeatability R from "
                 f"{_g(min(d['R_um'] for _, d in isos))} to {_g(max(d['R_um'] for _, d in isos))} µm."]
    table = CertTable(("axis", "travel (mm)", "targets", "runs", "A (µm)", "R (µm)", "E (µm)", "B (µm)", "M (µm)"),
                      tuple(rows), numeric=(2, 3, 4, 5, 6, 7, 8),
                      caption="Positioning (ISO 230-2, bidirectional): A accuracy, R repeatability, E systematic "
                              "deviation, B reversal value, M range of mean bidirectional deviation.")
    runs = sorted({d["runs"] for _, d in isos})
    statement = (f"Positioning: A and R are the values ISO 230-2 defines; they contain ±2s, s the estimator of the "
                 f"standard uncertainty of positioning from {', '.join(map(str, runs))} runs per direction at each "
                 f"target (the machine's repeatability, not the instrument's uncertainty).")
    return words, table, statement


def _verify_part(v):
    before, after = v["before_um"], v["after_um"]
    bmax, amax = v.get("before_max_3d_um"), v.get("after_max_3d_um")
    rows = tuple((name, *(_g(d[k]) for k in ("x", "y", "z", "3d")), "—" if mx is None else _g(mx))
                 for name, d, mx in (("before compensation", before, bmax), ("after compensation", after, amax)))
    table = CertTable(("tool point error", "x RMS (µm)", "y RMS (µm)", "z RMS (µm)", "3-D RMS (µm)", "3-D max (µm)"),
                      rows, numeric=(1, 2, 3, 4, 5),
                      caption=f"Verification run of {v['n_observations']} alignments with the compensation loaded; "
                              f"before: {v['before_source']}.")
    if v["at_noise_level"]:
        verdict = "what is left is at the level of the measurement noise: the compensation works"
    elif v["made_worse"]:
        verdict = "the error grew: the compensation made the machine worse and must not stay loaded"
    else:
        verdict = "an error above the measurement noise remains"
    words = [f"Compensation: the tool point error fell from {_g(before['3d'])} µm to {_g(after['3d'])} µm 3-D RMS; "
             f"{verdict}." if after["3d"] <= before["3d"] else
             f"Compensation: the tool point error went from {_g(before['3d'])} µm to {_g(after['3d'])} µm 3-D RMS; "
             f"{verdict}."]
    level = v.get("noise_level_3d_um")
    statement = ("Verification: RMS and maximum of the measured tool point error; the test of what is left against "
                 "the noise (α = 1 %) uses σ = " + ("—" if v.get("noise_um") is None else f"{_g(v['noise_um'])} µm")
                 + " per coordinate" + ("" if level is None else f", which alone leaves {_g(level)} µm 3-D RMS") + ".")
    return words, table, statement


def _fit_part(fit):
    import math

    machine = fit.machine
    significant, n_identified, k = [], 0, 0
    for e in fit.effects:
        sl = slice(k, k + e.n_params)
        k += e.n_params
        if machine.error_joint(e.code).axis in ("W", "T"):
            continue  # the set-up of the board and the sensor: not the machine's
        for name, v, s, u, ok in zip(fit.param_names[sl], fit.values[sl], fit.std[sl], fit.units[sl],
                                     fit.identifiable[sl]):
            if not ok or not math.isfinite(s) or s <= 0:
                continue
            n_identified += 1
            if abs(v) > K_EXPANDED * s:
                significant.append((abs(v) / s, name, v, K_EXPANDED * s, u))
    significant.sort(key=lambda t: -t[0])
    shown = significant[:MAX_ERROR_ROWS]
    rows = tuple((name, f"{v:+.{_decimals(U)}f}", f"{U:.{_decimals(U)}f}", unit) for _, name, v, U, unit in shown)
    more = len(significant) - len(shown)
    caption = (f"Geometric errors (ISO 230-1 codes) whose |value| exceeds U (k = {K_EXPANDED:g}), largest against U "
               f"first" + (f"; {more} more in the fit file" if more else "") + ".")
    table = CertTable(("error", "value", f"U (k = {K_EXPANDED:g})", "unit"), rows, numeric=(1, 2), caption=caption)
    words = [f"Geometric errors: {len(significant)} of the machine's {n_identified} identified error parameters exceed "
             f"their expanded uncertainty; the largest is {shown[0][1]} = {shown[0][2]:+.{_decimals(shown[0][3])}f} "
             f"{shown[0][4]} ± {shown[0][3]:.{_decimals(shown[0][3])}f} {shown[0][4]}." if shown else
             f"Geometric errors: none of the machine's {n_identified} identified error parameters exceeds its "
             f"expanded uncertainty."]
    source = {"given": "as given for the instrument", "replicates": "pooled from alignments repeated at the same pose",
              "fit": "as carried by the fit", "residuals": f"estimated from the fit's residuals ({fit.dof} degrees of "
                                                          f"freedom)"}.get(fit.noise_source, fit.noise_source)
    statement = (f"Geometric errors: the standard uncertainty of each is the square root of the diagonal of the fit's "
                 f"covariance σ²(JᵀJ)⁻¹ at the solution (J the Jacobian of the {fit.n_observations} alignments' "
                 f"residuals), σ = {_g(fit.noise_um)} µm per coordinate {source}; the fit left "
                 f"{_g(fit.rms_um)} µm RMS.")
    if fit.prior:
        statement += " The values are the maximum a posteriori estimate and U comes from the posterior (a prior on " \
                     "the errors' sizes)."
    if fit.shared_std:
        statement += f" It includes the type B uncertainty of {', '.join(sorted(fit.shared_std))}."
    return words, table, statement


def _decimals(U: float) -> int:
    """Decimals that show the expanded uncertainty to two significant digits (0 to 4)."""
    import math

    return 2 if not (math.isfinite(U) and U > 0) else min(4, max(0, 1 - math.floor(math.log10(U))))


def write_certificate(cert: Certificate, folder) -> Path:
    """Write ``certificate.pdf`` and ``certificate.html`` into ``folder``, whole or not at all (a folder that
    holds only an earlier certificate's files, or nothing, is replaced); returns the PDF's path.

    Raises
    ------
    DataError
        The content does not fit one A4 page even shrunk to :data:`MIN_SCALE`; the folder cannot be replaced.
    """
    from kinid.files import write_text
    from kinid.folders import listed_folder

    from .certificate_layout import certificate_html, certificate_pdf

    pdf, scale = certificate_pdf(cert)  # laid out before anything is written: refused whole
    with listed_folder(folder, written_by="kinid certificate") as stage:
        (stage / "certificate.pdf").write_bytes(pdf)
        write_text(stage / "certificate.html", certificate_html(cert, scale=scale))
    return Path(folder) / "certificate.pdf"
