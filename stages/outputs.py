"""The output options every stage command shares: ``--out``, ``--tables``, ``--plot``, ``--json`` and
``--report``, one definition with the command's own words (docs/cli.md).

Each stage command calls :func:`add_output_options` with the help text of the options it has and
passes the returned mapping on as ``outputs=`` (the roof checks those files and folders against the
command's inputs before it runs).

``--report DIR`` is written whole or not at all: the command checks the folder before its work
(:func:`check_report`) and writes the report inside :func:`staged_report`, which hands the report writer
the command's arguments with ``report`` naming a new folder that replaces ``DIR`` when the writer is done
(:func:`kinid.reports.html.report_folder`). ``--tables DIR`` too: checked by :func:`check_report`, written
inside :func:`staged_tables` (:func:`kinid.folders.listed_folder`).
"""
from __future__ import annotations

import contextlib

__all__ = ["add_output_options", "check_report", "refuse_unused", "staged_report", "staged_tables"]


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
        outputs["tables"] = "replaced folder"  # written whole (staged_tables): no input may lie in it
    if plot is not None:
        parser.add_argument("--plot", metavar=plot[0], help=plot[1])
        outputs["plot"] = "file"
    if json is not None:
        parser.add_argument("--json", action="store_true", help=json)
    if report is not None:
        parser.add_argument("--report", metavar=report[0], help=report[1])
        outputs["report"] = "replaced folder"  # written whole (staged_report): no input may lie in it
    return outputs


def refuse_unused(args, options, mode: str, instead: str) -> None:
    """One line, before any work, when an output option the chosen mode does not write is given (it would
    otherwise be silently ignored): ``options`` are destinations (``"report"``, ``"tables"``)."""
    from kinid.errors import DataError

    given = [o for o in options if getattr(args, o, None)]
    if given:
        names = " and ".join(f"--{o}" for o in given)
        raise DataError(f"{names} {'is' if len(given) == 1 else 'are'} not written with {mode}; {instead}")


def check_report(args) -> None:
    """Refuse ``--report DIR`` and ``--tables DIR`` before the command's work if they could not be replaced (a
    folder holding files that are not an earlier result of the command, a file, a read-only folder)."""
    if getattr(args, "report", None):
        from kinid.reports.html import check_report_folder

        check_report_folder(args.report)
    if getattr(args, "tables", None):
        from kinid.folders import check_listed_folder

        check_listed_folder(args.tables)


def staged_tables(args, command: str):
    """A new folder that replaces ``args.tables`` whole when the block ends (an error or Ctrl-C in the block
    leaves it as it was); ``command`` names the writer in its list of files."""
    from kinid.folders import listed_folder

    return listed_folder(args.tables, written_by=f"{command} --tables")


@contextlib.contextmanager
def staged_report(args):
    """A copy of ``args`` whose ``report`` names a new folder; when the block ends, that folder replaces
    ``args.report`` whole (an error or Ctrl-C in the block leaves ``args.report`` as it was).

    Examples
    --------
    >>> with staged_report(args) as staged:   # doctest: +SKIP
    ...     write_report(result, staged)
    """
    import argparse

    from kinid.reports.html import report_folder

    with report_folder(args.report) as stage:
        yield argparse.Namespace(**{**vars(args), "report": str(stage)})
