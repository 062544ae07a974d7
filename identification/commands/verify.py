"""``kinid verify``: the run after the compensation -> did it work, and what is left."""
from __future__ import annotations

from .data_input import add_export_options, read_data

__all__ = ["register"]


def register(sub) -> None:
    p = sub.add_parser(
        "verify", help="the run measured after loading the compensation: the error before and after, and what is left",
        description="Measure the machine again after loading the compensation (the same kind of run as the "
                    "first, readings as the controller shows them) and compare: the tool point error before "
                    "(predicted by the fit at the new poses, or measured in the first run with --before) and "
                    "after (what a fit of the board's and the sensor's set-up alone leaves), per coordinate "
                    "and 3-D; whether what is left is at the noise level; and a diagnosis of what remains "
                    "(docs/compensation.md).")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--fit", help="FIT.json the compensation was made from")
    src.add_argument("--compensation", metavar="DIR",
                     help="the folder kinid compensate wrote (its compensation.json names the fit and its SHA-256)")
    p.add_argument("--data", required=True,
                   help="observation CSV of the run made with the compensation loaded, or an instrument export read "
                        "as identify reads it (docs/formats.md, 'Instrument exports')")
    p.add_argument("--before", default=None, metavar="CSV",
                   help="observation CSV or instrument export of the first run (default: the error before is the "
                        "fit's prediction)")
    p.add_argument("--noise-um", type=float, default=None,
                   help="σ of one residual coordinate, µm (default: the fit's, where it was known)")
    p.add_argument("--allow-outside-limits", action="store_true",
                   help="accept readings outside the axis travel given by the URDF joint limits")
    p.add_argument("--json", action="store_true", help="print one JSON object (docs/cli.md)")
    p.add_argument("--report", default=None, metavar="DIR", help="write the verification report (HTML, figure) to DIR")
    add_export_options(p)
    p.set_defaults(run=_verify, outputs={"report": "replaced folder"})


def _fit_of_compensation(folder) -> str:
    """The fit a compensation folder was made from, checked against the SHA-256 it recorded."""
    import hashlib
    from pathlib import Path

    from kinid.errors import DataError
    from kinid.files import MAX_JSON_BYTES, read_json, read_untrusted_bytes
    from kinid.schema import Fields, Text, validate

    # what verify reads of a compensation.json (the rest is for people): the fit it was made from
    schema = Fields({"fit": Fields({"file": Text(), "sha256": Text()})}, other=True)

    marker = Path(folder) / "compensation.json"
    info = read_json(marker, what="compensation file")
    if not isinstance(info, dict) or info.get("fit") is None:
        raise DataError(f"{marker}: names no fit file; give it with --fit")
    validate(info, schema, path=marker)
    fit = info["fit"]
    path = Path(fit["file"])
    for candidate in (path, Path(folder) / path.name):
        if candidate.is_file():
            # the sized opener: a fit is a JSON file of at most MAX_JSON_BYTES, whatever compensation.json names
            digest = hashlib.sha256(read_untrusted_bytes(candidate, what="fit file", max_bytes=MAX_JSON_BYTES)).hexdigest()
            if digest != fit.get("sha256"):
                raise DataError(f"{candidate}: not the fit the compensation in {folder} was made from (its SHA-256 "
                                f"differs); give the right one with --fit")
            return str(candidate)
    raise DataError(f"{Path(folder) / 'compensation.json'}: its fit {fit['file']} is not found; give it with --fit")


def _verify(args) -> int:
    from pathlib import Path

    from kinid.checks import check_plausible, check_positive
    from kinid.files import strict_json
    from kinid.progress import step
    from ..fitting import load_trusted_fit
    from ..data import check_row_count
    from ..compensation import verify

    if args.noise_um is not None:
        check_positive("--noise-um", args.noise_um)
        check_plausible("--noise-um", args.noise_um, "sigma_um")
    if args.report:  # a folder it may not replace is refused before the work, not after
        from kinid.reports.html import check_report_folder

        check_report_folder(args.report)
    fit_path = args.fit or _fit_of_compensation(args.compensation)
    result = load_trusted_fit(fit_path)
    files = [f for f in (args.data, args.before) if f is not None]
    after, _ = read_data(args.data, result.machine, args, others=files)
    check_row_count(after, "a verification")
    before = None if args.before is None else read_data(args.before, result.machine, args, others=files)[0]
    if before is not None:
        check_row_count(before, "a verification")
    with step(f"fitting the set-up to the {len(after)} alignments of the run and judging what is left"):
        out = verify(result, after, before=before, noise_um=args.noise_um)
    if args.report:
        from ..compensation import verification_report

        with step(f"writing the report to {args.report}"):
            verification_report(out, args.report, fit_path=fit_path, data_path=args.data)
    if args.json:
        print(strict_json(out.summary()))
        return 0
    print(f"verification of the compensation of {Path(fit_path).name} with {Path(args.data).name}")
    print(out.text())
    if args.report:
        print(f"report written to {Path(args.report) / 'index.html'}")
    return 0
