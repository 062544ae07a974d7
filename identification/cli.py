"""The ``kinid`` command line (INTERFACES.md §4–§6).

Each package contributes its verbs through a ``register(subparsers)`` function
in the modules listed in :data:`VERB_MODULES`; a verb's parser sets
``run=function(args) -> int``. A :class:`~identification.errors.KinidError`
raised by a verb becomes one line on stderr and exit status 2.
"""
from __future__ import annotations

import argparse
import importlib
import sys

from .errors import KinidError

__all__ = ["main", "VERB_MODULES"]

#: Modules whose ``register(subparsers)`` adds verbs to ``kinid``.
VERB_MODULES = (
    "identification.commands",
    "vision.cli",
    "stages.backlash.cli",
    "stages.uvw.cli",
    "stages.dual_axis.cli",
    "stages.contour.cli",
)


class _Parser(argparse.ArgumentParser):
    """Argument errors as one line on stderr and exit status 2."""

    def error(self, message):  # noqa: D401 - argparse API
        self.exit(2, f"{self.prog}: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="kinid", description="Identify and compensate kinematic errors from vision measurements.")
    sub = parser.add_subparsers(dest="verb", metavar="VERB", parser_class=_Parser)
    sub.required = True
    for name in VERB_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:  # a real missing dependency inside the module
                raise
            continue
        module.register(sub)
    return parser


def limit_blas_threads() -> None:
    """Use one BLAS thread unless the user chose otherwise.

    kinid's matrices are small (at most a few thousand rows by a few hundred
    columns); on them OpenBLAS threads cost more than they give, and far more
    on a loaded machine (fit of the 336-alignment plan: 0.86 s threaded vs
    0.21 s single-threaded, measured on the 2-core development machine under
    load). Must run before numpy is imported.
    """
    import os

    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def main(argv=None) -> int:
    limit_blas_threads()
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        status = args.run(args)
    except KinidError as exc:
        print(f"kinid {args.verb}: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"kinid {args.verb}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # output piped into `head` and closed early: not an error of kinid
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    return 0 if status is None else int(status)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
