"""An option's old name kept as a hidden alias: it still works, and one warning names the new option."""
from __future__ import annotations

import argparse
import copy
import warnings

__all__ = ["add_alias", "add_positional_alias", "aliases_of", "canonical_argv", "OptionRenamed"]


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
