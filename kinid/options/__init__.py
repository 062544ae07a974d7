"""One vocabulary for every verb's options: old names kept as hidden aliases, and "did you mean" for a typo.

Every verb names the same thing the same way (the table is in docs/cli.md): the measurement a verb computes
from is ``--data``, the machine ``--machine``, the σ of a length ``--noise-um`` (``--noise-mm`` where mm is
natural), image noise ``--noise-grey``, a pixel's size ``--pixel-um``, what a verb writes ``--out``, its
result on standard output ``--json``. A name a verb used before stays as a hidden alias
(:func:`add_alias`): it still works, and one warning names the new option.

A typo gets a suggestion (:func:`did_you_mean`): an unknown verb, an unknown option or a value that is not one
of an option's choices is one line with the closest name, exit status 2 (kinid.cli's parser).

Modules: :mod:`.aliases` (old names), :mod:`.suggestions` (did you mean), :mod:`.json_result` (``--json``).
Imports only the standard library and the rest of the ground floor (no NumPy: building a parser stays light).
"""
from .aliases import OptionRenamed, add_alias, add_positional_alias, aliases_of, canonical_argv
from .json_result import WrittenJson, add_json_option, csv_rows, json_file, json_text
from .suggestions import did_you_mean, known_options

__all__ = ["add_alias", "add_positional_alias", "add_json_option", "csv_rows", "json_file", "json_text",
           "WrittenJson", "aliases_of", "canonical_argv", "did_you_mean", "known_options", "OptionRenamed"]
