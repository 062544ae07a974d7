"""Every verb refuses a bad file at the door, derived from every verb's parser, not case by case.

For each verb of ``kinid.cli.VERBS`` that reads files, every option that names a file to read (and every
positional one) is given one file of a corpus of bad files — empty, binary bytes, text in UTF-16, a JSON object
where a table is read, a table where JSON is read, a folder, a path that does not exist — all at once, so whichever
the verb reads first is bad. The outputs name fresh paths. The call must end with exit status 2 and one line on
stderr naming the bad file, no traceback, and nothing written.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from kinid.cli import DEFAULT_OUTPUTS, VERBS, main
from test_outputs_from_parsers import _verb_parser

#: The corpus: a name and the bytes written (None: a folder; "missing": no file at all).
BAD_FILES = {
    "empty": b"",
    "binary": bytes(range(256)) * 4,
    "utf16": "mark,wx_mm\nM1,1\n".encode("utf-16"),
    "json object": b'{"a": 1}\n',
    "table": b"a,b\n1,2\n",
    "folder": None,
    "missing": "missing",
}


#: The options of each verb that name a file (or folder) it reads; one of a mutually exclusive pair. A new file
#: option must be added here: :func:`test_every_file_option_is_listed` finds them by their metavar and name.
FILE_OPTIONS = {
    "plan": ("machine", "board", "augment", "data"),
    "simulate": ("machine", "errors", "plan"),
    "identify": ("machine", "data"),
    "diagnose": ("fit", "data"),
    "predict": ("fit", "poses"),
    "model": ("urdf",),
    "compensate": ("fit",),
    "verify": ("fit", "data", "before"),
    "sensor": ("machine", "hole", "base"),
    "observe": ("machine", "board", "sensor", "log", "fit"),
    "markers": ("image",),
    "backlash": ("log",),
    "uvw": ("moves",),
    "dual-axis": ("data",),
    "contour": ("frames", "board", "camera", "path_file"),
    "iso230-2": ("runs",),
    "certificate": ("fit", "verify", "iso", "meta"),
}
#: What a verb needs beside its files to reach them.
COMPANIONS = {"contour": ["--out", "OUT/track"], "dual-axis": ["--pixel-to-mm", "1", "0", "0", "1"]}
_FILE_WORDS = ("CSV", "JSON", "URDF", "DIR", "IMAGE", "FILE")
_FILE_DESTS = ("machine", "urdf", "fit", "data", "poses", "errors", "board", "sensor", "log", "moves", "runs", "frames")


def _actions(verb):
    sub = _verb_parser(verb)
    outputs = sub.get_default("outputs") or DEFAULT_OUTPUTS
    return sub, outputs, [a for a in sub._actions if a.dest != "help" and a.help != argparse.SUPPRESS]


def test_every_file_option_is_listed():
    """An option that names a file by its metavar (CSV, JSON, URDF, DIR, IMAGE) or its name is in FILE_OPTIONS, so a
    new file option is covered (an option exclusive with a listed one is covered by that one)."""
    for verb in VERBS:
        sub, outputs, actions = _actions(verb)
        exclusive = {a.dest for g in sub._mutually_exclusive_groups for a in g._group_actions
                     if any(b.dest in FILE_OPTIONS.get(verb, ()) for b in g._group_actions)}
        for a in actions:
            words = " ".join(a.metavar) if isinstance(a.metavar, tuple) else str(a.metavar or "")
            if a.dest in outputs or a.nargs == 0 or words.startswith("AXIS") or verb == "contour" and a.dest == "path":
                continue
            if any(w in words.upper() for w in _FILE_WORDS) or a.dest in _FILE_DESTS:
                assert a.dest in FILE_OPTIONS.get(verb, ()) or a.dest in exclusive, (verb, a.dest, words)


CASES = [(verb, bad) for verb in FILE_OPTIONS for bad in BAD_FILES]


def _argv(verb, bad_path, tmp_path):
    sub, outputs, actions = _actions(verb)
    argv, positional = [verb], []
    for a in actions:
        if a.dest in FILE_OPTIONS[verb]:
            value = str(bad_path)
        elif a.dest in outputs and (a.required or not a.option_strings):
            value = str(tmp_path / "OUT" / f"new_{a.dest}")
        elif a.required or not a.option_strings:
            value = str(a.choices[0]) if a.choices else ("1" if a.type in (int, float) else str(tmp_path / f"x_{a.dest}"))
        else:
            continue
        if a.option_strings:
            argv += [a.option_strings[-1], value]
        else:
            positional.append(value)
    extra = [str(tmp_path / w) if w.startswith("OUT") else w for w in COMPANIONS.get(verb, [])]
    return argv + extra + positional


def _unchanged(path, content) -> bool:
    """The bad input as it was: the same bytes, the folder still an empty folder, the missing file still missing."""
    if content is None:
        return path.is_dir() and not any(path.iterdir())
    if content == "missing":
        return not path.exists()
    return path.read_bytes() == content


def _written(tmp_path, before):
    return sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p not in before)


@pytest.mark.parametrize("verb, bad", CASES, ids=[f"{v}-{b}" for v, b in CASES])
def test_a_bad_file_is_refused_at_the_door(verb, bad, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    content = BAD_FILES[bad]
    path = tmp_path / f"bad_{bad.replace(' ', '_')}"
    if content is None:
        path.mkdir()
    elif content != "missing":
        path.write_bytes(content)
    before = set(tmp_path.rglob("*"))
    argv = _argv(verb, path, tmp_path)
    status = main(argv)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert status == 2, (argv, err)
    assert "Traceback" not in err, err
    assert lines and lines[-1].startswith("kinid"), err
    assert path.name in lines[-1], (argv, err)
    assert _written(tmp_path, before) == [], (argv, _written(tmp_path, before))
    assert _unchanged(path, BAD_FILES[bad]), path


#: A good file for each file option of the five-axis verbs (``FIT``/``OBS``: made by the fixture below), so that one
#: bad file among good ones is reached wherever the verb reads it.
_EX = Path(__file__).resolve().parent.parent / "examples"
GOOD = {"machine": _EX.parent / "urdf" / "five_axis_bc.urdf", "errors": _EX / "errors.json", "plan": _EX / "poses.csv",
        "poses": _EX / "poses.csv", "urdf": _EX / "ur_like.urdf", "board": _EX / "run" / "board.json",
        "sensor": _EX / "run" / "sensor.json", "log": _EX / "run" / "log.csv", "hole": _EX / "sensor_hole.csv",
        "base": _EX / "run" / "sensor.json", "fit": "FIT", "augment": "FIT", "data": "OBS", "before": "OBS"}
ONE_BAD = [(verb, dest, bad) for verb in ("plan", "simulate", "identify", "diagnose", "predict", "verify", "sensor",
                                          "observe") for dest in FILE_OPTIONS[verb] if len(FILE_OPTIONS[verb]) > 1
           for bad in ("binary", "table", "folder", "missing")]


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    d = tmp_path_factory.mktemp("good")
    assert main(["simulate", "--machine", str(GOOD["machine"]), "--errors", str(GOOD["errors"]), "--plan", "patent",
                 "--noise-um", "1", "--out", str(d / "obs.csv")]) == 0
    assert main(["identify", "--machine", str(GOOD["machine"]), "--data", str(d / "obs.csv"), "--noise-um", "1",
                 "--out", str(d / "fit.json")]) == 0
    return {"FIT": d / "fit.json", "OBS": d / "obs.csv"}


@pytest.mark.parametrize("verb, dest, bad", ONE_BAD, ids=[f"{v}-{d}-{b}" for v, d, b in ONE_BAD])
def test_one_bad_file_among_good_ones_is_named(verb, dest, bad, made, tmp_path, capsys, monkeypatch):
    """The same, one option at a time: the others name good files, so the refusal must name the bad one."""
    monkeypatch.chdir(tmp_path)
    path = tmp_path / f"bad_{bad}"
    if BAD_FILES[bad] is None:
        path.mkdir()
    elif BAD_FILES[bad] != "missing":
        path.write_bytes(BAD_FILES[bad])
    argv = _argv(verb, path, tmp_path)
    flags = {a.dest: a.option_strings[-1] for a in _actions(verb)[2] if a.option_strings}
    for other in FILE_OPTIONS[verb]:
        if other != dest:
            good = GOOD[other]
            argv[argv.index(flags[other]) + 1] = str(made.get(good, good))
    if verb == "plan" and dest not in ("augment", "data"):  # --augment comes with its --data; a first plan has neither
        for option in ("--augment", "--data"):
            i = argv.index(option)
            del argv[i:i + 2]
    before = set(tmp_path.rglob("*"))
    capsys.readouterr()
    status = main(argv)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert status == 2, (argv, err)
    assert "Traceback" not in err, err
    assert lines and lines[-1].startswith("kinid") and path.name in lines[-1], (argv, err)
    assert _written(tmp_path, before) == [], (argv, _written(tmp_path, before))
    assert _unchanged(path, BAD_FILES[bad]), path
