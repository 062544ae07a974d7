"""The closest name to a typo: an unknown verb, option, choice (difflib)."""
from __future__ import annotations

import argparse
import difflib

from .aliases import _AliasMixin

__all__ = ["did_you_mean", "known_options"]


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
