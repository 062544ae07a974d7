"""No verb can overwrite one of its inputs: derived from every verb's parser, not case by case.

For each verb of ``kinid.cli.VERBS`` and each of its file outputs (the ``outputs`` its parser declares, else
``DEFAULT_OUTPUTS``), the verb is called with that output naming a file given as one of its inputs (every other
option that takes a path). The check runs before the verb's work, so any contents do: the call must end with
exit status 2, one line naming both options, and the input byte for byte as it was.
"""
from __future__ import annotations

import argparse
import hashlib

import pytest

from kinid.cli import DEFAULT_OUTPUTS, VERBS, build_parser, main


def _verb_parser(verb):
    parser = build_parser(verb)
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[verb]


#: Options that take a text but name no file: a scheduler address, an axis name, effect names, axes, a paper size.
NOT_FILES = ("scheduler", "axis", "add", "solve", "page")


def _reads(a, outputs) -> bool:
    """Whether the option ``a`` names a file the verb reads."""
    return (a.dest not in outputs and a.dest != "help" and a.nargs in (None, "?") and a.type is None and not a.choices
            and a.const is None and a.dest not in NOT_FILES
            and not isinstance(a, (argparse._StoreTrueAction, argparse._StoreFalseAction)))


def _cases():
    out = []
    for verb in VERBS:
        sub = _verb_parser(verb)
        outputs = sub.get_default("outputs") or DEFAULT_OUTPUTS
        # an old option name kept as a hidden alias warns before its refusal: the aliases' own test is test_vocabulary
        actions = [a for a in sub._actions if a.dest != "help" and a.help != argparse.SUPPRESS]
        files = [a for a in actions if a.dest in outputs and outputs[a.dest] == "file" and a.option_strings]
        inputs = [a for a in actions if _reads(a, outputs)]
        exclusive = [set(g._group_actions) for g in sub._mutually_exclusive_groups]
        for o in files:
            for i in inputs:
                if any(o in g and i in g for g in exclusive):
                    continue  # never given together
                out.append((verb, o.option_strings[-1], i.option_strings[-1] if i.option_strings else i.dest))
    return out


CASES = _cases()


def test_every_verb_that_writes_a_file_is_covered():
    """Every verb with a file output and an option that names a file to read has cases (a verb that reads no file,
    such as board, has none to overwrite)."""
    verbs = {v for v, _, _ in CASES}
    writing = set()
    for v in VERBS:
        sub = _verb_parser(v)
        outputs = sub.get_default("outputs") or DEFAULT_OUTPUTS
        has_file_output = any(a.dest in outputs and outputs[a.dest] == "file" for a in sub._actions)
        reads = any(_reads(a, outputs) for a in sub._actions)
        if has_file_output and reads:
            writing.add(v)
    assert writing <= verbs, f"verbs with a file output and inputs but no case: {sorted(writing - verbs)}"
    assert len(verbs) >= 12, sorted(verbs)


def _argv(verb, output, source, path, tmp_path):
    """The verb's required options filled (numbers, the first choice, fresh paths), ``output`` and ``source``
    both naming ``path``."""
    sub = _verb_parser(verb)
    argv = [verb]
    given = {output, source}
    positional = []
    for a in sub._actions:
        if a.dest == "help" or a.help == argparse.SUPPRESS:  # a hidden alias (an old name, a read by position)
            continue
        name = a.option_strings[-1] if a.option_strings else a.dest
        if name == source and not a.option_strings:
            positional.append((a.dest, str(path)))
            continue
        if name in given:
            continue
        if not (a.required or not a.option_strings):
            continue
        value = str(a.choices[0]) if a.choices else ("1" if a.type in (int, float) else str(tmp_path / f"new_{a.dest}"))
        if a.option_strings:
            argv += [name, value]
        else:
            positional.append((a.dest, value))
    for group in sub._mutually_exclusive_groups:
        if group.required and not any((a.option_strings[-1] if a.option_strings else a.dest) in given
                                      for a in group._group_actions):
            a = group._group_actions[0]
            argv += [a.option_strings[-1]] if a.nargs == 0 else [a.option_strings[-1], str(tmp_path / "other_input")]
            (tmp_path / "other_input").write_text("x\n")
    argv += [output, str(path)]
    argv += [value for _, value in positional]
    if source in [a.option_strings[-1] for a in sub._actions if a.option_strings]:
        argv += [source, str(path)]
    return argv


@pytest.mark.parametrize("verb, output, source", CASES)
def test_no_output_may_overwrite_an_input(verb, output, source, tmp_path, capsys):
    path = tmp_path / "input.dat"
    path.write_bytes(b"target_mm,run,direction,deviation_um\n0,1,1,1\n")
    before = hashlib.sha256(path.read_bytes()).hexdigest()
    status = main(_argv(verb, output, source, path, tmp_path))
    err = capsys.readouterr().err
    assert status == 2, (verb, output, source, err)
    assert "never overwrites an input" in err and output in err, (verb, output, source, err)
    assert len([line for line in err.splitlines() if line.strip()]) == 1, err
    assert hashlib.sha256(path.read_bytes()).hexdigest() == before
