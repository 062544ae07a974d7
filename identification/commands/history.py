"""``kinid history``: a machine's calibrations in one database (add, show, plot), flagging which error grows."""
from __future__ import annotations

__all__ = ["register"]


#: ``--db`` when none is given: a file in the current folder (never a server).
DEFAULT_DB = "kinid_history.sqlite"


def register(sub) -> None:
    p = sub.add_parser(
        "history", help="a machine's calibrations over time in one database: which error grows",
        description="Keep each calibration of a machine in one SQLite database and follow its errors over time "
                    "(docs/history.md): `add` stores every term of a FIT.json (and the figures of kinid verify "
                    "--json) under a machine id and a date; `show` tables each term over the calibrations and "
                    "flags a term that moved beyond its combined uncertainty (k = 2) between consecutive "
                    "calibrations or beyond a tolerance given; `plot` draws the flagged terms with their "
                    "uncertainty bars.")
    verbs = p.add_subparsers(dest="history_verb", metavar="ACTION", parser_class=type(p),
                             help="add a calibration, show the terms over time, or plot them")
    verbs.required = True

    def common(q):
        q.add_argument("--db", default=DEFAULT_DB,
                       help=f"the history: a SQLite file, or sqlite:///PATH (relative) / sqlite:////PATH (absolute); "
                            f"default {DEFAULT_DB} in the current folder; no other scheme is supported")
        q.add_argument("--machine-id", required=True, metavar="ID", help="the machine's own name or serial number")
        # the library's argument names as this verb's options (the roof looks only one parser deep)
        q.set_defaults(parameter_options={"db": "--db", "machine_id": "--machine-id", "tolerances": "--tolerance",
                                          "date": "--date", "out": "--out", "fit": "--fit", "verify": "--verify"})

    a = verbs.add_parser("add", help="store a calibration (FIT.json) of a machine",
                         description="Store every term of FIT.json (name, value, std, unit) as the calibration of "
                                     "the machine on the date given, with the fit's SHA-256; a fit already in the "
                                     "history is refused. Written in one transaction, whole or not at all.")
    common(a)
    a.add_argument("--fit", required=True, help="FIT.json written by kinid identify")
    a.add_argument("--verify", default=None, metavar="VERIFY.json",
                   help="the output of kinid verify --json for this calibration's compensation (its figures are kept)")
    a.add_argument("--date", default=None, metavar="YYYY-MM-DD", help="date of the calibration (default: today)")
    a.set_defaults(run=_add, outputs={})

    s = verbs.add_parser("show", help="each term over time, flagged where it moved",
                         description="A table of each term over the machine's calibrations (value ± expanded "
                                     "uncertainty, k = 2, and the trend per year); a term is flagged where it moved "
                                     "by more than 2·√(σ₁² + σ₂²) between consecutive calibrations, or from its first "
                                     "value by more than a --tolerance given. The database is opened read-only.")
    common(s)
    s.add_argument("--tolerance", nargs="+", default=(), metavar="NAME=VALUE",
                   help="flag NAME (EX0C, EXX:periodic:10[sin]) when it departs from its first value by more than "
                        "VALUE, in its unit (µm or µrad)")
    s.add_argument("--last", type=int, default=None, metavar="N",
                   help="show only the latest N calibrations' columns (flags and trends use every one)")
    s.add_argument("--json", action="store_true", help="print one JSON object (docs/history.md)")
    s.set_defaults(run=_show, outputs={})

    g = verbs.add_parser("plot", help="the flagged terms over time with their uncertainty bars (PNG)",
                         description="Draw each flagged term (every term with --all) over the machine's calibrations "
                                     "with its expanded uncertainty (k = 2) as bars, one panel per term.")
    common(g)
    g.add_argument("--out", required=True, metavar="PNG", help="the figure to write (PNG, whole or not at all)")
    g.add_argument("--all", dest="every_term", action="store_true", help="every term, not only the flagged ones")
    g.add_argument("--tolerance", nargs="+", default=(), metavar="NAME=VALUE",
                   help="as for show: flag NAME beyond VALUE from its first value")
    g.set_defaults(run=_plot, outputs={"out": "file"})


def _tolerances(items) -> dict:
    import math

    from kinid.errors import DataError

    out = {}
    for item in items:
        name, sep, value = item.rpartition("=")
        try:
            number = float(value)
        except ValueError:
            number = float("nan")
        if not sep or not name or not math.isfinite(number) or number <= 0:
            raise DataError(f"--tolerance takes NAME=VALUE with VALUE a positive number in the term's unit, got {item!r}")
        if name in out:
            raise DataError(f"--tolerance gives {name!r} twice")
        out[name] = number
    return out


def _add(args) -> int:
    from ..compensation import add_calibration, database_path

    cal = add_calibration(args.db, args.machine_id, args.fit, verify_path=args.verify, date=args.date)
    print(f"calibration of {cal.machine_id} on {cal.date} added to {database_path(args.db)}: {cal.n_terms} terms of "
          f"{cal.fit_file} (SHA-256 {cal.fit_sha256[:12]}…)" + (", with its verification" if cal.verify else ""))
    return 0


def _show(args) -> int:
    from kinid.checks import check_positive
    from kinid.files import strict_json
    from ..compensation import history_text, machine_history

    if args.last is not None:
        check_positive("--last", args.last)
    history = machine_history(args.db, args.machine_id, tolerances=_tolerances(args.tolerance))
    print(strict_json(history.summary()) if args.json else history_text(history, last=args.last))
    return 0


def _plot(args) -> int:
    from ..compensation import machine_history, plot_history

    history = machine_history(args.db, args.machine_id, tolerances=_tolerances(args.tolerance))
    n = plot_history(history, args.out, every_term=args.every_term)
    print(f"{n} term{'s' if n != 1 else ''} of {args.machine_id} over {len(history.dates)} calibrations drawn to "
          f"{args.out}" + ("" if n or args.every_term else " (none flagged; --all for every term)"))
    return 0
