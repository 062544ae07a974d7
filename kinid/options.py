"""One vocabulary for every verb's options: old names kept as hidden aliases, and "did you mean" for a typo.

Every verb names the same thing the same way (the table is in docs/cli.md): the measurement a verb computes
from is ``--data``, the machine ``--machine``, the σ of a length ``--noise-um`` (``--noise-mm`` where mm is
natural), image noise ``--noise-grey``, a pixel's size ``--pixel-um``, what a verb writes ``--out``, its
result on standard output ``--json``. A name a verb used before stays as a hidden alias
(:func:`add_alias`): it still works, and one warning names the new option.

A typo gets a suggestion (:func:`did_you_mean`): an unknown verb, an unknown option or a value that is not one
of an option's choices is one line with the closest name, exit status 2 (kinid.cli's parser).
"""
from __future__ import annotations

import argparse
import copy
import difflib
import warnings

__all__ = ["add_alias", "add_positional_alias", "add_json_option", "csv_rows", "json_file", "aliases_of",
           "canonical_argv", "did_you_mean", "known_options", "OptionRenamed"]


class OptionRenamed(UserWarning):
    """An option given by its old name: it still works; the warning names the new one."""


class _AliasMixin:
    """An option's old name: warns once, naming the new option, then does what the new one does."""

    canonical: str = ""
    own_type: bool = False
    note: str = ""

    def __call__(self, parser, namespace, values, option_string=None):
        warn_renamed(option_string or self.option_strings[0], self.canonical, self.note)
        super().__call__(parser, namespace, values, option_string)


_ALIAS_CLASSES: dict = {}


def _alias_class(cls):
    if cls not in _ALIAS_CLASSES:
        _ALIAS_CLASSES[cls] = type(f"Alias{cls.__name__}", (_AliasMixin, cls), {})
    return _ALIAS_CLASSES[cls]


def warn_renamed(old: str, new: str, note: str = "") -> None:
    """The one line an old option name gives: ``--log is now --data (the old name still works)``."""
    warnings.warn(f"{old} is now {new}{note} (the old name still works)", OptionRenamed, stacklevel=3)


def add_alias(parser: argparse.ArgumentParser, old: str, new: str, *, reads=None, note: str = ""):
    """Keep ``old`` as a hidden alias of the option ``new`` of ``parser``.

    The alias sets what ``new`` sets (read by its own type ``reads`` where the unit changed: ``--pixel-um``
    reads µm into a mm value, its alias ``--pixel-mm`` reads mm), is
    not shown by ``--help``, belongs to ``new``'s mutually exclusive group, and warns once naming ``new``
    (``note`` is added to that line, e.g. ``" in µm: 1000 x the mm value"``).

    Returns
    -------
    argparse.Action
        The alias's action.
    """
    target = next((a for a in parser._actions if new in a.option_strings), None)
    if target is None:  # pragma: no cover - a bug of the verb's parser, not a user error
        raise ValueError(f"{parser.prog} has no option {new}")
    alias = copy.copy(target)
    alias.__class__ = _alias_class(type(target))
    alias.option_strings = [old]
    alias.help = argparse.SUPPRESS
    alias.required = False
    alias.default = argparse.SUPPRESS
    alias.canonical = new
    alias.note = note
    if reads is not None:
        alias.type, alias.own_type = reads, True
    for group in parser._mutually_exclusive_groups:
        if target in group._group_actions:
            group._group_actions.append(alias)
    parser._add_action(alias)
    return alias


class _PositionalAlias(argparse.Action):
    """A value once given by position, now an option: warns naming the option, then sets its destination."""

    canonical: str = ""

    def __call__(self, parser, namespace, values, option_string=None):
        if values is None:
            return
        if getattr(namespace, self.dest, None) is not None:
            parser.error(f"{values} given both by position and as {self.canonical}")
        warnings.warn(f"{self.metavar} by position is now {self.canonical} {self.metavar} (read by position still)",
                      OptionRenamed, stacklevel=2)
        setattr(namespace, self.dest, values)


def add_positional_alias(parser: argparse.ArgumentParser, metavar: str, new: str):
    """Accept the value of option ``new`` also by position (how the verb took it before), with one warning.

    ``new`` cannot then be required by argparse: the verb checks that its destination was given.
    """
    target = next(a for a in parser._actions if new in a.option_strings)
    alias = parser.add_argument(f"{target.dest}_by_position", metavar=metavar, nargs="?", default=None,
                                help=argparse.SUPPRESS, action=_PositionalAlias)
    alias.dest, alias.canonical = target.dest, new
    return alias


def aliases_of(parser: argparse.ArgumentParser) -> dict:
    """Old option name -> its alias action, for the options of ``parser`` (not its sub-commands')."""
    return {a.option_strings[0]: a for a in parser._actions if isinstance(a, _AliasMixin)}


def canonical_argv(parser: argparse.ArgumentParser, argv: list) -> list:
    """``argv`` with each old option name of ``parser`` written as its new name, one warning per old name.

    Needed where the new option is required (argparse counts only the action given); an alias that
    reads another unit is left to its own action.
    """
    renames = {old: a for old, a in aliases_of(parser).items() if not a.own_type}
    if not renames:
        return argv
    out, seen = [], set()
    for arg in argv:
        if arg == "--":
            out.extend(argv[len(out):])
            break
        name, eq, value = arg.partition("=")
        action = renames.get(name) if arg.startswith("--") else None
        if action is None:
            out.append(arg)
            continue
        if name not in seen:
            warn_renamed(name, action.canonical, action.note)
            seen.add(name)
        out.append(action.canonical + eq + value)
    return out


def known_options(parser: argparse.ArgumentParser) -> list:
    """The option names ``parser`` shows (aliases and ``-h`` left out), its sub-commands' too."""
    names = []
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            for sub in a.choices.values():
                names.extend(n for n in known_options(sub) if n not in names)
        elif a.help != argparse.SUPPRESS and not isinstance(a, _AliasMixin):
            names.extend(s for s in a.option_strings if s.startswith("--") and s != "--help")
    return names


def did_you_mean(word: str, choices, *, aliases=None) -> str:
    """`` (did you mean X?)`` with the closest of ``choices`` to ``word`` (difflib), or ``""``.

    ``aliases`` maps old names to new: a typo of an old name suggests the new one.
    """
    aliases = aliases or {}
    pool = list(choices) + [a for a in aliases if a not in choices]
    close = difflib.get_close_matches(word, pool, n=1, cutoff=0.6)
    if not close:
        return ""
    return f" (did you mean {aliases.get(close[0], close[0])}?)"


def add_json_option(parser: argparse.ArgumentParser, result, what: str) -> None:
    """``--json``: after the verb has run, its result ``result(args)`` printed as one strict JSON value on
    standard output, the verb's own text going to standard error (``what`` names the result in the help).

    For verbs whose result is the file they write (:func:`json_file`, :func:`csv_rows`): the roof
    (kinid.cli) prints it, so the verb's code is the same with or without ``--json``.
    """
    parser.add_argument("--json", action="store_true", help=f"print {what} as JSON on standard output (the "
                                                            "text goes to standard error)")
    parser.set_defaults(json_result=result)


def json_file(dest: str, name: str | None = None):
    """A ``result`` for :func:`add_json_option`: the JSON file the verb wrote at ``args.<dest>`` (inside it,
    ``name``, when ``args.<dest>`` is a folder)."""
    def result(args):
        from pathlib import Path

        from .untrusted import read_json

        path = Path(getattr(args, dest))
        return read_json(path / name if name else path)
    return result


def csv_rows(dest: str):
    """A ``result`` for :func:`add_json_option`: the rows of the CSV the verb wrote at ``args.<dest>``, one
    object per row (numbers as numbers, empty cells as null)."""
    def result(args):
        import csv
        import io

        from .untrusted import read_limited_text
        from .files import MAX_CSV_BYTES

        text = read_limited_text(getattr(args, dest), what="CSV file", max_bytes=MAX_CSV_BYTES)
        return [{k: _cell(v) for k, v in row.items()}
                for row in csv.DictReader(io.StringIO(text)) if any(row.values())]
    return result


def _cell(text):
    if text is None or text.strip() == "":
        return None
    try:
        return float(text) if any(c in text for c in ".eEn") else int(text)
    except ValueError:
        return text
