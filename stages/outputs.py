"""The output options every stage command shares: ``--out``, ``--tables``, ``--plot``, ``--json`` and
``--report``, one definition with the command's own words (docs/cli.md).

Each stage command calls :func:`add_output_options` with the help text of the options it has and
passes the returned mapping on as ``outputs=`` (the roof checks those files and folders against the
command's inputs before it runs).
"""
from __future__ import annotations

__all__ = ["add_output_options"]


def add_output_options(parser, *, out=None, tables=None, plot=None, json=None, report=None) -> dict:
    """Add the output options given, each as ``(metavar, help)`` (``json``: its help text).

    Returns
    -------
    dict
        Option destination -> "file" or "folder", for ``set_defaults(outputs=...)``.
    """
    outputs = {}
    if out is not None:
        parser.add_argument("--out", metavar=out[0], help=out[1])
        outputs["out"] = "file"
    if tables is not None:
        parser.add_argument("--tables", metavar=tables[0], help=tables[1])
        outputs["tables"] = "folder"
    if plot is not None:
        parser.add_argument("--plot", metavar=plot[0], help=plot[1])
        outputs["plot"] = "file"
    if json is not None:
        parser.add_argument("--json", action="store_true", help=json)
    if report is not None:
        parser.add_argument("--report", metavar=report[0], help=report[1])
        outputs["report"] = "folder"
    return outputs
