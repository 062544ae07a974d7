"""The ``kinid`` command line: the one roof over every package's verbs.

Each verb is listed in :data:`VERBS` with the module that implements it. The
module is imported only when its verb runs, so ``kinid --help`` and ``kinid
identify`` do not pay for OpenCV, the stage simulators or matplotlib. A verb
module provides ``register(subparsers)``, which adds its parsers and sets
``run=function(args) -> int`` on each. A :class:`~kinid.errors.KinidError`
raised by a verb becomes one line on stderr and exit status 2; Ctrl-C gives
one line and exit status 130, SIGTERM (``kill``, a job scheduler's stop) one line and 143 — both after what
the verb was writing has been put back (an output is the earlier one or the new one, whole).
"""
from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import sys
import warnings
from dataclasses import dataclass

from .errors import KinidError

__all__ = ["main", "build_parser", "VERBS", "Verb"]


@dataclass(frozen=True)
class Verb:
    """A command-line verb: the module that registers it and its one-line help."""

    module: str
    help: str


#: Every verb of ``kinid``, in the order ``kinid --help`` lists them.
VERBS = {
    "demo": Verb("kinid.identification.commands.identify", "the whole five-axis story on the built-in machine with a hidden effect"),
    "plan": Verb("kinid.identification.commands.plan", "the fewest alignments, ordered for machine time, that reach a stated accuracy"),
    "simulate": Verb("kinid.identification.commands.identify", "alignment readings of a machine with a known error set"),
    "identify": Verb("kinid.identification.commands.identify", "fit the default model plus added effects to alignment observations"),
    "diagnose": Verb("kinid.identification.commands.identify", "compare a fit with data and rank the effects that may be missing"),
    "predict": Verb("kinid.identification.commands.identify", "axis readings at which the fitted machine aligns the tool point with each mark"),
    "model": Verb("kinid.identification.commands.model", "an existing URDF (a ROS robot, a machine drawn elsewhere) -> a machine kinid can identify"),
    "compensate": Verb("kinid.identification.commands.compensate", "axis error tables, constants, a calibrated URDF and controller files from a fit"),
    "verify": Verb("kinid.identification.commands.verify", "the run after loading the compensation: error before and after, what is left"),
    "certificate": Verb("kinid.identification.commands.certificate", "a one-page certificate (PDF and HTML) for the customer to sign: fit, verification, ISO 230-2"),
    "history": Verb("kinid.identification.commands.history", "a machine's calibrations over time in one database: which error grows"),
    "sensor": Verb("kinid.identification.commands.sensor", "the laser's offset beside the camera from the hole or sphere set-up measurement"),
    "observe": Verb("kinid.identification.commands.observe", "images + axis readings of a run -> observation CSV (marks located and decoded)"),
    "board": Verb("kinid.vision.board_cli", "a printable ring-coded board (SVG and PDF at true scale) and its board file"),
    "markers": Verb("kinid.vision.cli", "detect and decode ring-coded marks in an image"),
    "backlash": Verb("kinid.stages.backlash.cli", "pixel equivalent and X/Y/θ lead-screw backlash of an X-Y-θ stage from images"),
    "uvw": Verb("kinid.stages.uvw.cli", "UVW alignment stage: compensation from measured moves"),
    "dual-axis": Verb("kinid.stages.dual_axis.cli", "offset table between two parallel Y axes of a gantry"),
    "contour": Verb("kinid.stages.contour.cli", "planar contour error from an image sequence of a ring-coded board"),
    "iso230-2": Verb("kinid.stages.iso230_2", "ISO 230-2 accuracy, repeatability and reversal of one axis from bidirectional runs"),
}


class _Parser(argparse.ArgumentParser):
    """Argument errors as one line on stderr and exit status 2, a typo with the closest name; an option's old
    name (a hidden alias, :func:`kinid.options.add_alias`) read as its new one with one warning."""

    def parse_known_args(self, args=None, namespace=None):
        from .options import canonical_argv

        if args is not None:
            args = canonical_argv(self, list(args))
            self._given = args
        return super().parse_known_args(args, namespace)

    def parse_args(self, args=None, namespace=None):
        parsed, extras = self.parse_known_args(args, namespace)
        if extras:
            _unknown_option(self, parsed, extras)
        return parsed

    def error(self, message):  # noqa: D401 - argparse API
        unknown = [a for a in getattr(self, "_given", ()) if a.startswith("--") and a != "--"
                   and not any(o.startswith(a.partition("=")[0]) for o in self._option_string_actions)]
        if unknown and message.startswith("the following arguments are required"):
            _unknown_option(self, argparse.Namespace(), unknown)  # the typo, not what it left missing
        self.exit(2, f"{self.prog}: {_with_suggestion(message)}\n")


def _with_suggestion(message: str) -> str:
    """argparse's 'invalid choice' with the closest choice first: ``invalid choice: 'identfy' (did you mean
    identify?)``; other messages as they are."""
    import re

    from .options import did_you_mean

    m = re.search(r"invalid choice: '?(.*?)'? \(choose from (.*)\)$", message)
    if not m:
        return message
    choices = [c.strip().strip("'") for c in m.group(2).split(",")]
    hint = did_you_mean(m.group(1), choices)
    if message.startswith("argument VERB:"):
        return f"unknown verb '{m.group(1)}'{hint}; kinid --help lists the verbs"
    return message[:m.start(2) - len("(choose from ")] + (hint.strip() + " " if hint else "") + \
        f"(choose from {m.group(2)})"


def _unknown_option(parser, parsed, extras) -> None:
    """One line for arguments no option of the verb takes, naming the closest option of the verb."""
    from .options import aliases_of, did_you_mean, known_options

    verb_parser = parser
    sub = next((a for a in parser._actions if isinstance(a, argparse._SubParsersAction)), None)
    if sub is not None and getattr(parsed, sub.dest, None) in sub.choices:
        verb_parser = sub.choices[getattr(parsed, sub.dest)]
    options = known_options(verb_parser)
    renamed = {old: a.canonical for old, a in aliases_of(verb_parser).items()}
    word = next((e for e in extras if e.startswith("-")), extras[0])
    if word.startswith("-"):
        name = word.partition("=")[0]
        verb_parser.error(f"unknown option {name}{did_you_mean(name, options, aliases=renamed)}; "
                          f"{verb_parser.prog} --help lists its options")
    verb_parser.error(f"unrecognized arguments: {' '.join(extras)}")


def _version() -> str:
    from . import __version__

    return __version__


class _Version(argparse._VersionAction):
    """``--version``, which reads the installed version only when it is asked for."""

    def __call__(self, parser, namespace, values, option_string=None):
        self.version = f"kinid {_version()}"
        super().__call__(parser, namespace, values, option_string)


def build_parser(verb: str | None = None) -> argparse.ArgumentParser:
    """The ``kinid`` parser; the full parser of ``verb`` only (others get their help line).

    Importing the module of ``verb`` is the only import this makes.
    """
    parser = _Parser(prog="kinid", description="Identify and compensate kinematic errors of machine tools and "
                                               "precision stages from vision measurements.")
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(dest="verb", metavar="VERB", parser_class=_Parser)
    sub.required = True
    if verb in VERBS:
        importlib.import_module(VERBS[verb].module).register(sub)
        if verb not in sub.choices:  # pragma: no cover - a packaging bug, not a user error
            raise RuntimeError(f"module {VERBS[verb].module} does not register the verb {verb!r}")
    for name, v in VERBS.items():
        if name not in sub.choices:
            sub.add_parser(name, help=v.help, add_help=False)
    # list the verbs in VERBS order whatever was registered first
    sub._choices_actions.sort(key=lambda a: list(VERBS).index(a.dest) if a.dest in VERBS else len(VERBS))
    return parser


def _option_for(parser: argparse.ArgumentParser, args, verb: str | None, parameter: str) -> str | None:
    """The command-line option that sets the library argument ``parameter``, if the verb has one.

    The one place where argument names become option names: a verb's parser
    may declare ``parameter_options={"n_targets": "--targets"}`` in its
    defaults; otherwise an option whose ``dest`` is the argument's name is it.
    """
    declared = getattr(args, "parameter_options", None) or {}
    if parameter in declared:
        return declared[parameter]
    sub = next((a for a in parser._actions if isinstance(a, argparse._SubParsersAction)), None)
    verb_parser = sub.choices.get(verb) if sub is not None and verb else None
    for action in verb_parser._actions if verb_parser is not None else ():
        if action.dest == parameter and action.option_strings and not getattr(action, "canonical", None):
            return max(action.option_strings, key=len)
    return None


#: Options that name what a verb writes, and whether each is a file or a folder. A verb whose
#: options differ declares ``outputs={dest: kind}`` in its parser's defaults.
DEFAULT_OUTPUTS = {"out": "file", "plot": "file", "draw": "file", "report": "folder"}


def _check_files(parser, args, verb) -> None:
    """Before a verb runs: no output may overwrite an input or another output, or be a device or folder."""
    from .files import check_outputs

    outputs = getattr(args, "outputs", None) or DEFAULT_OUTPUTS
    skip = {"run", "outputs", "parameter_options", "verb", "json_result"}

    def option(dest):
        return _option_for(parser, args, verb, dest) or dest

    outs = [(option(dest), getattr(args, dest), kind) for dest, kind in outputs.items()
            if isinstance(getattr(args, dest, None), str)]
    ins = []
    for dest, value in vars(args).items():
        if dest in outputs or dest in skip:
            continue
        for v in value if isinstance(value, list) else [value]:
            if isinstance(v, str) and v and v != "-" and os.path.exists(v):
                ins.append((option(dest), v))
    check_outputs(outs, ins)


def _chosen_verb(argv) -> str | None:
    for arg in argv:
        if not arg.startswith("-"):
            return arg
    return None


def main(argv=None) -> int:
    """Run ``kinid`` with ``argv`` (default: ``sys.argv[1:]``); returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    # numpy-heavy verbs work on small matrices, where threaded BLAS costs more than it gives; the
    # library limits itself around the fit and the diagnosis, this covers the rest of a command
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    _keep_freed_memory()
    with warnings.catch_warnings(), _terminate_as_interrupt():
        return _run(argv)


#: glibc's mallopt parameters, and the values the command sets: arrays up to 1 GB come from the heap (not a mapping
#: of their own each), and up to 1 GB freed at its top is kept for the next ones. On bench_read's 10⁶ rows: the
#: kernel's CPU time 1.8–2.2 s → 1.2 s, peak memory 727 → 732 MB (32 MB for the first: 1.8 s, 791 MB).
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
KEEP_FREED_BYTES, HEAP_ARRAY_BYTES = 1 << 30, 1 << 30


def _keep_freed_memory() -> None:
    """On glibc, keep memory freed by numpy for the next arrays instead of giving it back to the kernel and asking
    again: a fit over 10⁶ rows makes and drops many arrays of every row, and the kernel's zeroing of fresh pages
    was ≈ 1 s of its CPU time (``benchmarks/bench_read.py``). Called by :func:`main` (the process of a
    command, or of a program that runs ``main``); the library alone leaves the allocator as it is. Elsewhere
    (macOS, Windows) nothing changes."""
    if not sys.platform.startswith("linux"):
        return
    import ctypes

    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return
    mallopt(M_MMAP_THRESHOLD, HEAP_ARRAY_BYTES)
    mallopt(M_TRIM_THRESHOLD, KEEP_FREED_BYTES)


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the process is, so that every ``finally`` and staged output is put back as for Ctrl-C."""


@contextlib.contextmanager
def _terminate_as_interrupt():
    """While a verb runs, SIGTERM raises :class:`Terminated` (only where nobody else handles SIGTERM, and only in
    the main thread: a program that embeds kinid keeps its own handler)."""
    import signal
    import threading

    def raise_terminated(signum, frame):
        raise Terminated()

    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGTERM) != signal.SIG_DFL:
        yield
        return
    signal.signal(signal.SIGTERM, raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _run(argv) -> int:
    verb = parser = args = None
    try:
        verb = _chosen_verb(argv)
        # the library's warnings (a value that looks wrong but is valid) as one line each, not Python's format
        warnings.showwarning = lambda message, *rest, **kw: print(f"kinid {verb}: warning: {message}", file=sys.stderr)
        parser = build_parser(verb)
        args = parser.parse_args(argv)
        _check_files(parser, args, verb)
        to_stdout = "-" in (getattr(args, dest, None) for dest in (getattr(args, "outputs", None) or DEFAULT_OUTPUTS))
        result = getattr(args, "json_result", None) if getattr(args, "json", False) else None
        if result is not None and to_stdout:
            raise KinidError("--json and an output '-' both print to standard output: give one of them")
        if to_stdout or result is not None:
            # the data go to standard output: the verb's messages go to standard error
            with contextlib.redirect_stdout(sys.stderr):
                status = args.run(args)
        else:
            status = args.run(args)
        if result is not None and not status:
            from .options import json_text

            print(json_text(result(args)))
    except KinidError as exc:
        if exc.parameter is not None and parser is not None:
            option = _option_for(parser, args, verb, exc.parameter)
            exc = exc.renamed(option) if option else exc
        print(f"kinid {verb}: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        stopped = "terminated" if isinstance(exc, Terminated) else "interrupted"
        print(f"kinid{' ' + verb if verb else ''}: {stopped}", file=sys.stderr)
        return 143 if isinstance(exc, Terminated) else 130
    except BrokenPipeError:  # output piped into `head` and closed early: not an error of kinid
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:  # the file system said no where no writer of kinid's caught it (a folder made)
        from .untrusted import shown_path

        where = f"{shown_path(exc.filename)}: " if exc.filename else ""
        print(f"kinid {verb}: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    return 0 if status is None else int(status)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
