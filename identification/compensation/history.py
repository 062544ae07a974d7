"""A machine's calibrations over time in one database: which error grows (docs/history.md).

- :func:`database_path` — ``--db``: a file path or a ``sqlite:///PATH`` URL (the only scheme; a database
  server would be named by its URL, and is refused here with its scheme named);
- :func:`add_calibration` — every parameter of a FIT.json (name, value, std, unit) under a machine id and a
  date, with the fit's SHA-256 and, if given, the figures of ``kinid verify --json``; a fit already in the
  history is refused;
- :func:`machine_history` — the terms of one machine over time, each flagged where it moved beyond its
  combined expanded uncertainty between consecutive calibrations (|Δ| > k·√(σ₁² + σ₂²), k = 2) or beyond a
  tolerance given, with its trend per year.

Storage is stdlib :mod:`sqlite3`: one file, written in one transaction per calibration (a calibration is
in the history whole or not at all); ``show`` and ``plot`` open it read-only.
"""
from __future__ import annotations

import datetime as _dt
import hashlib
import math
import re
import sqlite3
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import quote

import numpy as np

from kinid.errors import DataError
from ..fitting import load_trusted_fit

__all__ = ["SCHEMES", "K_MOVED", "HISTORY_FORMAT", "database_path", "add_calibration",
           "machine_history", "Calibration", "TermTrend", "History"]

#: URL schemes ``--db`` takes.
SCHEMES = ("sqlite",)
#: Coverage factor of the combined uncertainty a term must move beyond to be flagged.
K_MOVED = 2.0
#: The value of the ``format`` row of a kinid history's ``kinid_meta`` table.
HISTORY_FORMAT = "kinid-history-1"
#: The first bytes of every SQLite 3 database file.
SQLITE_HEADER = b"SQLite format 3\x00"

_TABLES = """
CREATE TABLE kinid_meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE calibrations (
    id INTEGER PRIMARY KEY, machine_id TEXT NOT NULL, date TEXT NOT NULL, fit_sha256 TEXT NOT NULL UNIQUE,
    fit_file TEXT NOT NULL, machine_sha256 TEXT NOT NULL, added_utc TEXT NOT NULL, rms_um REAL, noise_um REAL,
    n_observations INTEGER, verify_file TEXT, verify_json TEXT, before_3d_um REAL, after_3d_um REAL,
    noise_level_3d_um REAL, at_noise_level INTEGER);
CREATE TABLE terms (
    calibration_id INTEGER NOT NULL REFERENCES calibrations(id), name TEXT NOT NULL, kind TEXT NOT NULL,
    value REAL, std REAL, unit TEXT NOT NULL, identified INTEGER NOT NULL, PRIMARY KEY (calibration_id, name));
CREATE INDEX calibrations_of_machine ON calibrations (machine_id, date);
"""


# --- the database ------------------------------------------------------------------------------

def database_path(db) -> Path:
    """The SQLite file ``db`` names: a path, or ``sqlite:///relative/path`` / ``sqlite:////absolute/path``.

    Raises
    ------
    DataError
        A URL of another scheme (``postgresql://`` ...), or ``sqlite://`` without a file.
    """
    text = str(db)
    m = re.match(r"^([A-Za-z][A-Za-z0-9+.\-]*)://(.*)$", text)
    if m is None:
        return Path(text)
    scheme, rest = m.group(1).lower(), m.group(2)
    if scheme.split("+")[0] not in SCHEMES:
        raise DataError(f"gives the scheme {m.group(1)!r}, which is not supported: kinid history stores in SQLite only "
                        f"(a file path, or sqlite:///PATH)", parameter="db")
    if not rest.startswith("/") or rest == "/":
        raise DataError(f"{text!r} names no file: sqlite:///PATH (relative) or sqlite:////PATH (absolute)",
                        parameter="db")
    return Path(rest[1:].split("?")[0])


def _connect(path: Path, *, write: bool) -> sqlite3.Connection:
    """An open kinid history at ``path``: created when ``write`` and missing or empty, read-only otherwise."""
    exists = path.exists()
    if not exists and not write:
        raise DataError(f"{path}: no history database here; `kinid history add` creates it")
    if exists:
        if path.is_dir():
            raise DataError(f"{path}: a folder, not a history database file")
        try:
            with open(path, "rb") as f:
                head = f.read(len(SQLITE_HEADER))
        except OSError as exc:
            raise DataError(f"{path}: cannot read ({exc.strerror or exc})") from None
        if head and head != SQLITE_HEADER:
            raise DataError(f"{path}: not a SQLite database (it does not start with 'SQLite format 3'); --db names the "
                            f"file `kinid history add` writes")
    uri = f"file:{quote(str(path.resolve()))}?mode={'rwc' if write else 'ro'}"
    try:
        conn = sqlite3.connect(uri, uri=True, timeout=30.0)
        tables = {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        if not tables and write:
            with conn:
                conn.executescript(_TABLES)
                conn.execute("INSERT INTO kinid_meta VALUES ('format', ?)", (HISTORY_FORMAT,))
            return conn
        fmt = conn.execute("SELECT value FROM kinid_meta WHERE key = 'format'").fetchone() \
            if "kinid_meta" in tables else None
    except sqlite3.DatabaseError as exc:
        raise DataError(f"{path}: not a usable SQLite database ({exc})") from None
    if fmt is None or fmt[0] != HISTORY_FORMAT:
        conn.close()
        raise DataError(f"{path}: a SQLite database but not a kinid history (no kinid_meta format "
                        f"{HISTORY_FORMAT!r}); give another --db")
    return conn


# --- adding a calibration ----------------------------------------------------------------------

@dataclass(frozen=True)
class Calibration:
    """One calibration of a machine as the history holds it (figures of the verification where given)."""

    machine_id: str
    date: str
    fit_sha256: str
    fit_file: str
    n_terms: int
    verify: dict | None = None


def _check_date(text) -> str:
    if text is None:
        return _dt.date.today().isoformat()
    if not re.fullmatch(r"\d{4}-\d{2}-\d{2}", str(text)):
        raise DataError(f"takes a date as YYYY-MM-DD, got {text!r}", parameter="date")
    try:
        return _dt.date.fromisoformat(text).isoformat()
    except ValueError:
        raise DataError(f"{text!r} is no calendar date (YYYY-MM-DD)", parameter="date") from None


def _check_machine_id(machine_id) -> str:
    text = str(machine_id)
    if not text.strip() or len(text) > 200 or not text.isprintable():
        raise DataError(f"must be 1 to 200 printable characters, got {text[:40]!r}", parameter="machine_id")
    return text


def _verify_figures(path) -> tuple:
    """(JSON text, figures) of a ``kinid verify --json`` output file."""
    import json

    from kinid.files import read_json
    from kinid.schema import Fields, Flag, Number, Text, validate

    um = Fields({k: Number(low=0) for k in ("x", "y", "z", "3d")})
    schema = Fields({"before_um": um, "after_um": um, "noise_level_3d_um": Number(low=0),
                     "at_noise_level": Flag()}, optional={"before_source": Text()}, other=True)
    data = read_json(path, what="verification (kinid verify --json)")
    validate(data, schema, path=path)
    figures = {"before_3d_um": float(data["before_um"]["3d"]), "after_3d_um": float(data["after_um"]["3d"]),
               "noise_level_3d_um": float(data["noise_level_3d_um"]), "at_noise_level": bool(data["at_noise_level"])}
    return json.dumps(data, ensure_ascii=False), figures


def add_calibration(db, machine_id: str, fit_path, *, verify_path=None, date=None) -> Calibration:
    """Store the fit at ``fit_path`` as the calibration of ``machine_id`` on ``date`` (default: today).

    Every parameter of the fit is stored (name, value, std, unit, identified, and whether it is the set-up
    of the board or the sensor). One fit is one calibration: a fit already in the history (its SHA-256) is
    refused. Written in one transaction: the calibration is in the history whole or not at all.

    Raises
    ------
    DataError
        A missing or untrusted fit, a bad date, a verification file that is not ``kinid verify --json``'s
        output, a ``db`` that is not a kinid history, a fit already added.
    """
    machine_id = _check_machine_id(machine_id)
    date = _check_date(date)
    fit_path = Path(fit_path)
    if not fit_path.is_file():
        raise DataError(f"{fit_path}: no such fit file (FIT.json of kinid identify)")
    raw = fit_path.read_bytes()
    result = load_trusted_fit(fit_path)
    verify_json, figures = _verify_figures(verify_path) if verify_path is not None else (None, None)
    sha = hashlib.sha256(raw).hexdigest()
    machine_sha = result.machine.urdf_sha256
    rows, k = [], 0
    for e in result.effects:
        kind = "setup" if result.machine.error_joint(e.code).axis in ("W", "T") else "machine"
        for j in range(k, k + e.n_params):
            ok = bool(result.identifiable[j])
            value = float(result.values[j]) if ok and math.isfinite(result.values[j]) else None
            std = float(result.std[j]) if ok and math.isfinite(result.std[j]) else None
            rows.append((result.param_names[j], kind, value, std, result.units[j], int(ok)))
        k += e.n_params
    path = database_path(db)
    conn = _connect(path, write=True)
    try:
        same = conn.execute("SELECT machine_id, date FROM calibrations WHERE fit_sha256 = ?", (sha,)).fetchone()
        if same is not None:
            raise DataError(f"{fit_path}: this fit is already in the history {path} (machine {same[0]}, calibration of "
                            f"{same[1]}); a calibration is added once")
        earlier = conn.execute("SELECT machine_sha256 FROM calibrations WHERE machine_id = ? ORDER BY date DESC, id DESC",
                               (machine_id,)).fetchone()
        if earlier is not None and earlier[0] != machine_sha:
            import warnings

            warnings.warn(f"{fit_path}: its machine's URDF differs from the earlier calibrations of {machine_id}; "
                          f"terms the URDFs share are compared as if the same", stacklevel=2)
        with conn:  # one transaction
            cur = conn.execute(
                "INSERT INTO calibrations (machine_id, date, fit_sha256, fit_file, machine_sha256, added_utc, rms_um, "
                "noise_um, n_observations, verify_file, verify_json, before_3d_um, after_3d_um, noise_level_3d_um, "
                "at_noise_level) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (machine_id, date, sha, str(fit_path), machine_sha,
                 _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
                 _finite(result.rms_um), _finite(result.noise_um), int(result.n_observations),
                 None if verify_path is None else str(verify_path), verify_json,
                 *((None,) * 4 if figures is None else (figures["before_3d_um"], figures["after_3d_um"],
                                                        figures["noise_level_3d_um"], int(figures["at_noise_level"])))))
            conn.executemany("INSERT INTO terms VALUES (?, ?, ?, ?, ?, ?, ?)",
                             [(cur.lastrowid, *r) for r in rows])
    except sqlite3.DatabaseError as exc:
        raise DataError(f"{path}: the history could not be written ({exc}); nothing was added") from None
    finally:
        conn.close()
    return Calibration(machine_id, date, sha, str(fit_path), len(rows), figures)


def _finite(x):
    x = float(x)
    return x if math.isfinite(x) else None


# --- a machine's history -----------------------------------------------------------------------

@dataclass(frozen=True)
class TermTrend:
    """One term of a machine over its calibrations.

    Attributes
    ----------
    name, unit : str
        ISO 230-1 name (``EX0C``, ``EXX:periodic:10[sin]``) and µm / µrad.
    kind : str
        "machine", or "setup" (the board's or the sensor's placement: new at every set-up, not flagged
        unless a tolerance is given for it).
    values, std : tuple of float or None
        Per calibration (None where the fit did not identify it or has no such term).
    flags : tuple of str
        Why the term is flagged, one line each (empty: not flagged).
    trend_per_year, trend_std_per_year : float or None
        Weighted straight-line slope over the identified values (three or more) and its standard deviation.
    """

    name: str
    unit: str
    kind: str
    values: tuple
    std: tuple
    flags: tuple
    trend_per_year: float | None
    trend_std_per_year: float | None

    @property
    def flagged(self) -> bool:
        return bool(self.flags)


@dataclass(frozen=True)
class History:
    """A machine's calibrations (oldest first) and its terms over them."""

    machine_id: str
    database: str
    dates: tuple
    calibrations: tuple  # dicts: date, fit_sha256, fit_file, verify figures or None
    terms: tuple
    k: float
    tolerances: dict
    comparisons: int

    @property
    def flagged(self) -> tuple:
        return tuple(t for t in self.terms if t.flagged)

    def summary(self) -> dict:
        """The JSON object of ``kinid history show --json`` (docs/history.md)."""
        return {"machine_id": self.machine_id, "database": self.database, "k": self.k,
                "tolerances": dict(self.tolerances), "calibrations": [dict(c) for c in self.calibrations],
                "flagged": [t.name for t in self.flagged],
                "comparisons": self.comparisons,
                "terms": [{"name": t.name, "unit": t.unit, "kind": t.kind, "flagged": t.flagged, "flags": list(t.flags),
                           "trend_per_year": t.trend_per_year, "trend_std_per_year": t.trend_std_per_year,
                           "points": [{"date": d, "value": v, "std": s}
                                      for d, v, s in zip(self.dates, t.values, t.std)]}
                          for t in self.terms]}


def _trend(days, values, std):
    """Weighted least-squares slope per year and its standard deviation, or (None, None)."""
    keep = [(d, v, s) for d, v, s in zip(days, values, std) if v is not None and s is not None and s > 0]
    if len(keep) < 3 or len({d for d, _, _ in keep}) < 2:
        return None, None
    t = np.array([d for d, _, _ in keep], float) / 365.25
    y = np.array([v for _, v, _ in keep], float)
    w = 1.0 / np.array([s for _, _, s in keep], float)
    A = np.column_stack([np.ones_like(t), t - t.mean()]) * w[:, None]
    coef, *_ = np.linalg.lstsq(A, y * w, rcond=None)
    cov = np.linalg.pinv(A.T @ A)
    return float(coef[1]), float(np.sqrt(cov[1, 1]))


def machine_history(db, machine_id: str, *, tolerances=None, k: float = K_MOVED) -> History:
    """The calibrations of ``machine_id`` in ``db`` (oldest first) and each term's flags and trend.

    A term is flagged where, between consecutive calibrations that both identified it, it moved by more
    than ``k`` times the combined standard deviation, |Δ| > k·√(σ₁² + σ₂²) (k = 2); or, for a term named in
    ``tolerances`` (name -> µm or µrad), where it departs from its first value by more than the tolerance.
    The set-up terms are new at every set-up and are flagged only by a tolerance given for them.

    Raises
    ------
    DataError
        No such database, not a kinid history, or no calibration of ``machine_id`` in it (the ids it holds
        are named).
    """
    path = database_path(db)
    tolerances = dict(tolerances or {})
    conn = _connect(path, write=False)
    try:
        cals = conn.execute("SELECT id, date, fit_sha256, fit_file, rms_um, before_3d_um, after_3d_um, "
                            "noise_level_3d_um, at_noise_level FROM calibrations WHERE machine_id = ? "
                            "ORDER BY date, id", (machine_id,)).fetchall()
        if not cals:
            ids = [r[0] for r in conn.execute("SELECT DISTINCT machine_id FROM calibrations ORDER BY machine_id")]
            shown = ", ".join(ids[:20]) + (" ..." if len(ids) > 20 else "") if ids else "none yet"
            raise DataError(f"{machine_id!r} has no calibration in {path}; machines in it: {shown}",
                            parameter="machine_id")
        rows = conn.execute("SELECT t.calibration_id, t.name, t.kind, t.value, t.std, t.unit FROM terms t JOIN "
                            "calibrations c ON c.id = t.calibration_id WHERE c.machine_id = ? ORDER BY c.date, c.id, t.rowid",
                            (machine_id,)).fetchall()
    except sqlite3.DatabaseError as exc:
        raise DataError(f"{path}: the history could not be read ({exc})") from None
    finally:
        conn.close()
    unknown = sorted(set(tolerances) - {r[1] for r in rows})
    if unknown:
        raise DataError(f"names no term of machine {machine_id!r}: {', '.join(unknown)}", parameter="tolerances")
    place = {c[0]: i for i, c in enumerate(cals)}
    dates = tuple(c[1] for c in cals)
    first = _dt.date.fromisoformat(dates[0])
    days = [(_dt.date.fromisoformat(d) - first).days for d in dates]
    table = {}
    for cid, name, kind, value, std, unit in rows:
        entry = table.setdefault(name, {"kind": kind, "unit": unit, "v": [None] * len(cals), "s": [None] * len(cals)})
        entry["v"][place[cid]], entry["s"][place[cid]] = value, std
    terms, comparisons = [], 0
    for name, e in table.items():
        flags = []
        seen = [(i, v, s) for i, (v, s) in enumerate(zip(e["v"], e["s"])) if v is not None and s is not None]
        for (i, v1, s1), (j, v2, s2) in zip(seen, seen[1:]):
            if e["kind"] != "machine":
                break
            comparisons += 1
            limit = k * math.hypot(s1, s2)
            if abs(v2 - v1) > limit:
                flags.append(f"moved {v2 - v1:+.3g} {e['unit']} from {dates[i]} to {dates[j]}, beyond "
                             f"{limit:.3g} {e['unit']} (k = {k:g})")
        if name in tolerances and seen:
            i0, v0 = seen[0][0], seen[0][1]
            over = [(j, v) for j, v, _ in seen[1:] if abs(v - v0) > tolerances[name]]
            if over:
                j, v = over[0]
                flags.append(f"{v - v0:+.3g} {e['unit']} from {dates[i0]} on {dates[j]}, beyond the tolerance "
                             f"{tolerances[name]:g} {e['unit']}")
        slope, slope_std = _trend(days, e["v"], e["s"])
        terms.append(TermTrend(name, e["unit"], e["kind"], tuple(e["v"]), tuple(e["s"]), tuple(flags), slope,
                               slope_std))
    terms.sort(key=lambda t: (t.kind != "machine", not t.flagged))  # stable: the fit's order within each group
    calibrations = tuple({"date": c[1], "fit_sha256": c[2], "fit_file": c[3], "rms_um": c[4],
                          "verify": None if c[5] is None else
                          {"before_3d_um": c[5], "after_3d_um": c[6], "noise_level_3d_um": c[7],
                           "at_noise_level": bool(c[8])}} for c in cals)
    return History(machine_id, str(path), dates, calibrations, tuple(terms), float(k), tolerances, comparisons)
