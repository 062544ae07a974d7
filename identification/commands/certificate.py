"""``kinid certificate``: the one-page certificate a customer signs (PDF and HTML), docs/certificate.md."""
from __future__ import annotations

__all__ = ["register"]


def register(sub) -> None:
    p = sub.add_parser(
        "certificate", help="a one-page certificate (PDF and HTML) of a fit, a verification and ISO 230-2 results",
        description="Write certificate.pdf and certificate.html, one A4 page each, for the customer to sign: the "
                    "machine, customer, operator, instrument and its calibration, temperatures (the metadata "
                    "file), the results in plain words (ISO 230-2 accuracy and repeatability per axis, the error "
                    "before and after the compensation, the significant geometric errors with U, k = 2), the "
                    "uncertainty statement, the fit's SHA-256 and kinid's version, and signature lines "
                    "(docs/certificate.md). Give at least one of --fit, --verify, --iso.")
    p.add_argument("--fit", metavar="FIT.json", help="the fit (kinid identify --out): its significant geometric errors")
    p.add_argument("--verify", metavar="VERIFY.json",
                   help="kinid verify's result: the file of `kinid verify --json > VERIFY.json` or its --report folder")
    p.add_argument("--iso", metavar="ISO.json", nargs="+", default=[],
                   help="kinid iso230-2 --json results, one file per axis")
    p.add_argument("--meta", metavar="META.json", required=True,
                   help="machine, serial number, customer, operator, instrument and its calibration, temperatures "
                        "(examples/certificate_meta.json)")
    p.add_argument("--out", metavar="DIR", required=True, help="the folder to write certificate.pdf and .html into")
    p.add_argument("--json", action="store_true", help="print one JSON object: the files written and the page's values")
    p.set_defaults(run=_certificate, outputs={"out": "replaced folder"})


def _certificate(args) -> int:
    from datetime import date

    from kinid.files import strict_json
    from kinid.folders import check_listed_folder
    from kinid.progress import step
    from ..reporting import build_certificate, read_meta, write_certificate

    meta = read_meta(args.meta)
    check_listed_folder(args.out)  # a folder it could not replace is refused before the work
    with step(f"writing the certificate to {args.out} (PDF and HTML)"):
        cert = build_certificate(meta, fit_path=args.fit, verify_path=args.verify, iso_paths=args.iso,
                                 issued=date.today().isoformat())
        pdf = write_certificate(cert, args.out)
    if args.json:
        from dataclasses import asdict
        from pathlib import Path

        print(strict_json({"files": [str(Path(args.out) / f) for f in ("certificate.pdf", "certificate.html")],
                           **asdict(cert)}))
        return 0
    for w in cert.warnings:
        print(f"warning (on the page): {w}")
    print(f"certificate written to {pdf} and {pdf.with_suffix('.html')}")
    return 0
