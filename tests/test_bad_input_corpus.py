"""Bad or unusual input on the command line: one line naming the file, line or column; exit status 2.

Each case runs ``kinid`` in-process (``kinid.cli.main``) and asserts the exit
status, that standard error is exactly one line matching the expected
message, that no traceback escapes, and that no input file changed.
"""
from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from kinid.cli import main
from kinid.urdf import path as urdf_path

ERRORS = {"EX0C": 12.0, "EA0B": -25.0}


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    """A folder with a machine, an error set, observations, a fit and an image."""
    d = tmp_path_factory.mktemp("corpus")
    shutil.copy(urdf_path("five_axis_bc"), d / "m.urdf")
    (d / "errors.json").write_text(json.dumps(ERRORS))
    cwd = os.getcwd()
    os.chdir(d)
    try:
        assert main(["simulate", "--machine", "m.urdf", "--errors", "errors.json", "--noise-um", "1",
                     "--out", "obs.csv"]) == 0
        assert main(["identify", "--machine", "m.urdf", "--data", "obs.csv", "--noise-um", "1",
                     "--out", "fit.json"]) == 0
    finally:
        os.chdir(cwd)
    import cv2

    cv2.imwrite(str(d / "img.png"), np.full((40, 60), 128, np.uint8))
    return d


def _digest(folder: Path) -> dict:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.iterdir() if p.is_file()}


def _text(d, name, text):
    (d / name).write_text(text, encoding="utf-8")
    return name


def _bytes(d, name, data):
    (d / name).write_bytes(data)
    return name


def _fit_with(d, name, **changes):
    data = json.loads((d / "fit.json").read_text(encoding="utf-8"))
    data.update(changes)
    (d / name).write_text(json.dumps(data), encoding="utf-8")
    return name


def _obs_with(d, name, edit):
    lines = (d / "obs.csv").read_text(encoding="utf-8").splitlines()
    (d / name).write_text("\n".join(edit(lines)) + "\n", encoding="utf-8")
    return name


ID = ["identify", "--machine", "m.urdf", "--data"]

CASES = [
    # outputs that would destroy inputs
    ("out is the data", lambda d: ID + ["obs.csv", "--out", "obs.csv"], r"obs\.csv: --out names the input file given as --data"),
    ("out is the data, other spelling", lambda d: (d / "sub").mkdir(exist_ok=True) or ID + ["obs.csv", "--out", "sub/../obs.csv"],
     r"--out names the input file given as --data"),
    ("out is the machine", lambda d: ID + ["obs.csv", "--out", "m.urdf"], r"--out names the input file given as --machine"),
    ("simulate out is the error set", lambda d: ["simulate", "--machine", "m.urdf", "--errors", "errors.json", "--out", "errors.json"],
     r"--out names the input file given as --errors"),
    ("predict out is the fit", lambda d: ["predict", "--fit", "fit.json", "--poses", "obs.csv", "--out", "fit.json"],
     r"--out names the input file given as --fit"),
    ("markers draw onto the image", lambda d: ["markers", "img.png", "--draw", "img.png"], r"--draw names the input file given as image"),
    ("report folder holds the data", lambda d: ID + ["obs.csv", "--out", "f2.json", "--report", "."],
     r"the --report folder holds the input given as --data"),
    ("out is a device", lambda d: ID + ["obs.csv", "--out", "/dev/null"], r"not a regular file"),
    ("out is a folder", lambda d: (d / "afolder").mkdir(exist_ok=True) or ID + ["obs.csv", "--out", "afolder"], r"is a folder"),
    ("out is empty", lambda d: ID + ["obs.csv", "--out", ""], r"--out is empty"),
    ("out folder missing", lambda d: ID + ["obs.csv", "--out", "nowhere/f.json"], r"output folder 'nowhere' does not exist"),
    # files that are not what they should be
    ("machine missing", lambda d: ["identify", "--machine", "none.urdf", "--data", "obs.csv", "--out", "f.json"], r"none\.urdf: machine file not found"),
    ("machine is a folder", lambda d: (d / "dir.urdf").mkdir(exist_ok=True) or ["identify", "--machine", "dir.urdf", "--data", "obs.csv", "--out", "f.json"],
     r"dir\.urdf: is a folder, not a machine file"),
    ("machine not UTF-8", lambda d: ["identify", "--machine", _bytes(d, "l1.urdf", b"<robot name='r'>\xff</robot>"), "--data", "obs.csv", "--out", "f.json"],
     r"l1\.urdf:1: machine file is not UTF-8"),
    ("machine with entities", lambda d: ["identify", "--machine", _text(d, "ent.urdf", '<?xml version="1.0"?><!DOCTYPE r [<!ENTITY a "aaaa">]><robot name="r"/>'),
                                         "--data", "obs.csv", "--out", "f.json"], r"DOCTYPE or entities"),
    ("machine 5000 nested links", lambda d: ["identify", "--machine", _text(d, "deep.urdf", "<robot name='r'><link name='l0'/>" + "".join(
        f"<link name='l{i + 1}'/><joint name='j{i}' type='fixed'><parent link='l{i}'/><child link='l{i + 1}'/></joint>" for i in range(5000)) + "</robot>"),
        "--data", "obs.csv", "--out", "f.json"], r"deep\.urdf: URDF has 5000 joints"),
    ("machine axis 0 0 0", lambda d: ["identify", "--machine", _text(d, "ax0.urdf", (d / "m.urdf").read_text().replace('<axis xyz="1 0 0"/>', '<axis xyz="0 0 0"/>', 1)),
                                     "--data", "obs.csv", "--out", "f.json"], r"axis xyz='0 0 0' is not a non-zero direction"),
    ("machine invalid for the URDF parser", lambda d: ["identify", "--machine", _text(d, "nolim.urdf", "<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='revolute'><parent link='a'/><child link='b'/></joint></robot>"),
                                                       "--data", "obs.csv", "--out", "f.json"], r"nolim\.urdf: not a valid URDF"),
    ("error set not UTF-8", lambda d: ["simulate", "--machine", "m.urdf", "--errors", _bytes(d, "e1.json", b'{"EX0C": "\xff"}'), "--out", "o.csv"],
     r"e1\.json:1: error-set file is not UTF-8"),
    ("error set a folder", lambda d: (d / "edir.json").mkdir(exist_ok=True) or ["simulate", "--machine", "m.urdf", "--errors", "edir.json", "--out", "o.csv"],
     r"edir\.json: is a folder"),
    ("error set deep", lambda d: ["simulate", "--machine", "m.urdf", "--errors", _text(d, "e2.json", "[" * 5000 + "]" * 5000), "--out", "o.csv"],
     r"e2\.json: error-set file nests deeper than"),
    ("error set NaN", lambda d: ["simulate", "--machine", "m.urdf", "--errors", _text(d, "e3.json", '{"EX0C": NaN}'), "--out", "o.csv"],
     r"e3\.json: error-set file holds NaN"),
    ("period far below sampling", lambda d: ["simulate", "--machine", "m.urdf", "--errors", _text(d, "e4.json", '{"EXX:periodic:1e-320": [1, 0]}'), "--out", "o.csv"],
     r"the period must be at least"),
    ("data cell too long", lambda d: ID + [_obs_with(d, "long.csv", lambda ls: ls[:1] + [ls[1].replace("M1", "M" + "x" * 200000, 1)] + ls[2:]), "--out", "f.json"],
     r"long\.csv:2: .*(field larger than field limit|limit of)"),
    ("reading far outside travel", lambda d: ID + [_obs_with(d, "far.csv", lambda ls: ls[:1] + [re.sub(r"^([^,]*,[^,]*,[^,]*,[^,]*,)[^,]*", r"\g<1>1e300", ls[1])] + ls[2:]),
                                                   "--out", "f.json"], r"far\.csv:2, column 'x_mm': 1e\+300 mm is outside the travel of axis X"),
    ("data not UTF-8", lambda d: ID + [_bytes(d, "b.csv", (d / "obs.csv").read_bytes()[:200] + b"\xff\n"), "--out", "f.json"], r"b\.csv:\d+: CSV file is not UTF-8"),
    ("data a folder", lambda d: (d / "ddir.csv").mkdir(exist_ok=True) or ID + ["ddir.csv", "--out", "f.json"], r"ddir\.csv: is a folder"),
    # fit files
    ("fit effects not names", lambda d: ["diagnose", "--fit", _fit_with(d, "f1.json", effects=[1, 2]), "--data", "obs.csv"], r"f1\.json: effects\[0\]: must be a string, got 1"),
    ("fit noise zero", lambda d: ["diagnose", "--fit", _fit_with(d, "f2.json", noise_um=0), "--data", "obs.csv"], r"f2\.json: noise_um: must be a number in \(0, 1e\+07\], got 0"),
    ("fit noise negative", lambda d: ["diagnose", "--fit", _fit_with(d, "f3.json", noise_um=-1), "--data", "obs.csv"], r"f3\.json: noise_um: must be a number in \(0, 1e\+07\], got -1"),
    ("fit deep", lambda d: ["diagnose", "--fit", _text(d, "f4.json", "{\"a\":" * 3000 + "1" + "}" * 3000), "--data", "obs.csv"], r"f4\.json: fit file nests deeper"),
    ("fit Infinity", lambda d: ["diagnose", "--fit", _text(d, "f5.json", (d / "fit.json").read_text().replace('"rank":', '"rank": Infinity, "r2":')), "--data", "obs.csv"],
     r"f5\.json: fit file holds Infinity"),
    # images
    ("image bomb header", lambda d: ["markers", _bytes(d, "bomb.png", b"\x89PNG\r\n\x1a\n" + b"\x00\x00\x00\x0dIHDR" + (100000).to_bytes(4, "big") * 2 + b"\x08\x00\x00\x00\x00" + b"\x00" * 4)],
     r"bomb\.png: image of 100000 × 100000 pixels is larger than the limit"),
    ("image not an image", lambda d: ["markers", _text(d, "txt.png", "hello")], r"txt\.png: cannot decode"),
    # arguments
    ("library argument named as its option", lambda d: ["backlash", "--simulate", "--targets", "0"], r"--targets must be an integer >= 1, got 0"),
]


@pytest.mark.parametrize("name, argv, expected", CASES, ids=[c[0] for c in CASES])
def test_bad_input_gives_one_line_and_status_2(workdir, capsys, monkeypatch, name, argv, expected):
    refused_in(workdir, capsys, monkeypatch, name, argv, expected)


def refused_in(workdir, capsys, monkeypatch, name, argv, expected):
    """Run ``argv(workdir)`` in ``workdir``: exit 2, one line on stderr matching ``expected``, no traceback, and no
    file of the folder changed (the other corpora, tests/test_door_checks.py, run their cases through it too)."""
    monkeypatch.chdir(workdir)
    before = _digest(workdir)
    args = argv(workdir)
    before.update({k: v for k, v in _digest(workdir).items() if k not in before})  # files the case wrote as input
    capsys.readouterr()
    status = main(args)
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert status == 2, f"{name}: exit {status}, stderr {err!r}"
    assert len(lines) == 1, f"{name}: expected one line, got {lines!r}"
    assert re.search(expected, lines[0]), f"{name}: {lines[0]!r} does not match {expected!r}"
    assert "Traceback" not in err
    after = _digest(workdir)
    changed = [k for k, v in before.items() if after.get(k) != v]
    assert not changed, f"{name}: input files changed: {changed}"
    written = sorted(set(after) - set(before))
    assert not written, f"{name}: files written: {written}"


def test_exact_duplicate_rows_are_not_replicates(workdir, capsys, monkeypatch):
    monkeypatch.chdir(workdir)
    _obs_with(workdir, "tripled.csv", lambda ls: ls[:1] + [ln for ln in ls[1:] for _ in range(3)])
    assert main(["identify", "--machine", "m.urdf", "--data", "obs.csv", "--out", "once.json"]) == 0
    capsys.readouterr()
    assert main(["identify", "--machine", "m.urdf", "--data", "tripled.csv", "--out", "thrice.json"]) == 0
    err = capsys.readouterr().err
    assert "672 row(s) repeat an earlier row exactly" in err and "each measurement is used once" in err
    once = json.loads((workdir / "once.json").read_text())
    thrice = json.loads((workdir / "thrice.json").read_text())
    assert thrice["n_observations"] == once["n_observations"] == 336
    assert thrice["noise_um"] == pytest.approx(once["noise_um"], rel=1e-9)


def _run(args, cwd):
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-m", "kinid", *args], cwd=cwd, capture_output=True, text=True, timeout=120)


def test_standard_output_dash(workdir):
    out = _run(["simulate", "--machine", "m.urdf", "--errors", "errors.json", "--out", "-"], workdir)
    assert out.returncode == 0
    assert out.stdout.startswith("mark,wx_mm,wy_mm,wz_mm,") and len(out.stdout.splitlines()) == 337
    assert "written to -" in out.stderr


def test_third_party_parser_output_is_folded_into_one_line(workdir):
    """urdfdom writes its own lines to file descriptor 2; the user sees only kinid's line, which quotes it."""
    _text(workdir, "nolim2.urdf", "<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='revolute'>"
                                  "<parent link='a'/><child link='b'/></joint></robot>")
    out = _run(["identify", "--machine", "nolim2.urdf", "--data", "obs.csv", "--out", "f.json"], workdir)
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert re.match(r"kinid identify: nolim2\.urdf: not a valid URDF \(.*the URDF parser said: .*does not specify limits",
                    lines[0]), lines[0]
