"""Every input a newer verb takes is checked at the door: one line naming the file or option, exit status 2.

Cases found by a reliability corpus, by class: (1) the shared JSON reader (a key given twice, an integer of 5 000
digits, a number too large for a float); (2) the source URDF of ``kinid model`` (not XML, cut off, entities,
a loop, xacro, names that do not print, joint names kinid would not read back); (3) numbers at the door (σ,
sizes, counts and times within plausible bounds per unit); (4) too few rows for the computation asked; (5) limits
checked before the work, and promises a command cannot keep. Each runs through ``kinid.cli.main`` with the
corpus runner of tests/test_bad_input_corpus.py: exit 2, one line matching the message, no traceback, no file of
the folder changed and none written.
"""
from __future__ import annotations

import json

from pathlib import Path

import pytest

from kinid.cli import main
from test_bad_input_corpus import refused_in, workdir  # noqa: F401 (workdir: the corpus's fixture)

FIT = ["diagnose", "--fit"]


def _text(d, name, text):
    (d / name).write_text(text, encoding="utf-8")
    return name


def _bytes(d, name, data):
    (d / name).write_bytes(data)
    return name


def _fit_text(d, name, edit):
    return _text(d, name, edit((d / "fit.json").read_text(encoding="utf-8")))


def _chain_urdf(names, link=lambda i: f"l{i}"):
    """A serial arm of revolute joints ``names``, from link ``base`` to link ``flange``."""
    links = ["base"] + [link(i) for i in range(1, len(names))] + ["flange"]
    joints = "".join(f"<joint name='{n}' type='revolute'><origin xyz='0 0 0.1'/><parent link='{links[i]}'/>"
                     f"<child link='{links[i + 1]}'/><axis xyz='0 0 1'/>"
                     f"<limit lower='-3' upper='3' effort='1' velocity='1'/></joint>" for i, n in enumerate(names))
    return "<robot name='arm'>" + "".join(f"<link name='{k}'/>" for k in links) + joints + "</robot>"


def _model(d, name, text, *extra):
    return ["model", "--urdf", _text(d, name, text), "--tool", "flange", "--out", "made.urdf", *extra]


JSON_CASES = [
    ("fit key twice", lambda d: FIT + [_fit_text(d, "dup.json", lambda t: t.replace('"rank":', '"rank": 3, "rank":', 1)),
                                       "--data", "obs.csv"], r"dup\.json:\d+: fit file gives the key 'rank' twice"),
    ("error set key twice", lambda d: ["simulate", "--machine", "m.urdf", "--errors",
                                       _text(d, "dup_e.json", '{"EX0C": 12,\n "EX0C": -3}'), "--out", "o.csv"],
     r"dup_e\.json:2: error-set file gives the key 'EX0C' twice"),
    ("integer of 5000 digits", lambda d: ["simulate", "--machine", "m.urdf", "--errors",
                                          _text(d, "big_e.json", '{"EX0C": ' + "9" * 5000 + "}"), "--out", "o.csv"],
     r"big_e\.json:1: error-set file holds an integer of 5,000 digits .*column 10"),
    ("number beyond a float", lambda d: FIT + [_fit_text(d, "inf.json", lambda t: t.replace('"rank":', '"r": 1e400, "rank":', 1)),
                                               "--data", "obs.csv"], r"inf\.json:\d+: fit file holds 1e400, which is too large"),
    ("cut-off JSON", lambda d: FIT + [_fit_text(d, "cut.json", lambda t: t[:len(t) // 2]), "--data", "obs.csv"],
     r"cut\.json:\d+: not valid JSON: .* \(column \d+\)"),
]

MODEL_CASES = [
    ("not XML", lambda d: _model(d, "text.urdf", "hello"), r"text\.urdf:1: not valid XML \(syntax error at column 1\)"),
    ("cut-off XML", lambda d: _model(d, "cut.urdf", _chain_urdf(["j1", "j2"])[:200]),
     r"cut\.urdf:1: not valid XML \(unclosed token at column \d+\)"),
    ("billion laughs", lambda d: _model(d, "lol.urdf", '<?xml version="1.0"?>\n<!DOCTYPE r [<!ENTITY a "aaaa">' + "".join(
        f'<!ENTITY a{i} "{"&a;" * 10 if i == 0 else f"&a{i - 1};" * 10}">' for i in range(9)) + ']>\n<robot name="r"><link name="&a8;"/></robot>'),
     r"lol\.urdf: URDF declares a DOCTYPE or entities"),
    ("external entity", lambda d: _model(d, "ext.urdf", '<?xml version="1.0"?><!-- ' + "x" * 5000 + ' -->\n<!DOCTYPE r [<!ENTITY x SYSTEM '
                                         '"file:///etc/passwd">]><robot name="r"><link name="&x;"/></robot>'),
     r"ext\.urdf: URDF declares a DOCTYPE or entities"),
    ("link cycle", lambda d: _model(d, "loop.urdf", "<robot name='r'><link name='a'/><link name='flange'/>"
                                    "<joint name='j1' type='fixed'><parent link='a'/><child link='flange'/></joint>"
                                    "<joint name='j2' type='fixed'><parent link='flange'/><child link='a'/></joint></robot>"),
     r"loop\.urdf: link '(a|flange)' is its own ancestor"),
    ("xacro include", lambda d: _model(d, "arm.urdf", "<robot name='r' xmlns:xacro='http://www.ros.org/wiki/xacro'>"
                                       "<xacro:include filename='arm.xacro'/><link name='flange'/></robot>"),
     r"arm\.urdf: holds xacro macros \(<xacro:include>\).*run xacro first"),
    ("xacro prefix undeclared", lambda d: _model(d, "arm2.urdf", "<robot name='r'><xacro:include filename='a'/></robot>"),
     r"arm2\.urdf:1: not valid XML \(unbound prefix .*run xacro first"),
    ("tool link missing, names escaped", lambda d: ["model", "--urdf", _text(d, "ctl.urdf", _chain_urdf(["j1"], ).replace(
        "'flange'", "'fl\x9b31m\u202eange'")), "--tool", "flange", "--out", "made.urdf"],
     r"ctl\.urdf: --tool names no link 'flange' in the URDF; links: base, 'fl\\x9b31m\\u202eange'$"),
    ("workpiece not below base", lambda d: _model(d, "wp.urdf", _chain_urdf(["j1", "j2"]), "--base", "l1", "--workpiece", "base"),
     r"wp\.urdf: --workpiece names link 'base', which is not below link 'l1'"),
    ("no root link", lambda d: _model(d, "noroot.urdf", "<robot name='r'/>"), r"noroot\.urdf: .*(no root link|no link)"),
]

HOLE = "role,x_mm,y_mm,z_mm,b_deg,c_deg\n" + "".join(f"camera,{c},0,0,0,0\nlaser,{c + 518},0,0,0,0\n" for c in (0, 0.001, 0.002))
PLAN = ["plan", "--machine", "m.urdf", "--out", "p.csv"]

NUMBER_CASES = [
    ("identify σ 1e-300 µm", lambda d: ["identify", "--machine", "m.urdf", "--data", "obs.csv", "--noise-um", "1e-300",
                                        "--out", "f.json"], r"--noise-um must be a number in \[0\.0001, 100000\] \(σ in µm\), got 1e-300"),
    ("diagnose σ 1e300 µm", lambda d: ["diagnose", "--fit", "fit.json", "--data", "obs.csv", "--noise-um", "1e300"],
     r"--noise-um must be a number in \[0\.0001, 100000\] \(σ in µm\)"),
    ("sensor σ 1e300 mm", lambda d: ["sensor", "--machine", "m.urdf", "--hole", _text(d, "hole.csv", HOLE), "--noise-mm", "1e300",
                                     "--out", "s.json"], r"--noise-mm must be a number in \[1e-07, 100\] \(σ in mm\), got 1e\+300"),
    ("sensor stand-off 1e-30 mm", lambda d: ["sensor", "--machine", "m.urdf", "--sphere", _text(d, "hole.csv", HOLE),
                                             "--standoff-mm", "1e-30", "--out", "s.json"], r"--standoff-mm must be a number in \[0\.0001, 100000\]"),
    ("plan σ 1e300 µm", lambda d: PLAN + ["--noise-um", "1e300"], r"--noise-um must be a number in \[0\.0001, 100000\]"),
    ("plan alignment 1e308 s", lambda d: PLAN + ["--align-s", "1e308"], r"--align-s must be a number in \[0, 1e\+06\] \(time in s\)"),
    ("plan speed 1e-300", lambda d: PLAN + ["--speed-mm-s", "1e-300"], r"--speed-mm-s must be a number in \[0\.001, 1e\+06\]"),
    ("iso230-2 deviation 1e155 µm", lambda d: ["iso230-2", "--data", _text(d, "runs.csv", "target_mm,run,direction,deviation_um\n" + "".join(
        f"{t},{r},{s},{1e155 if (t, r, s) == (10, 2, -1) else 1.5}\n" for t in (0, 10) for r in (1, 2) for s in (1, -1))), "--json"],
     r"runs\.csv:\d+, column 'deviation_um': a deviation of 1e\+155 µm is beyond 1e\+06 µm"),
    ("compensate step 1e-9 mm", lambda d: ["compensate", "--fit", "fit.json", "--out", "comp", "--step-mm", "1e-9"],
     r"--step-mm must be a number in \[0\.001, 10000\] \(step in mm\), got 1e-09"),
]

PROMISE_CASES = [
    ("sensor laser 518 mm away", lambda d: ["sensor", "--machine", "m.urdf", "--hole", _text(d, "hole.csv", HOLE), "--out", "s.json"],
     r"hole\.csv: the readings put the laser 518 mm from the camera's axis, more than 200 mm: not on the same tool"),
    ("axis number superscript", lambda d: ["compensate", "--fit", "fit.json", "--out", "comp", "--axis-number", "X=²"],
     r"--axis-number takes AXIS=N with N a whole number from 1 to 64, got 'X=²'"),
    ("axis number of 23 digits", lambda d: ["compensate", "--fit", "fit.json", "--out", "comp", "--axis-number",
                                            "X=99999999999999999999999"], r"--axis-number takes AXIS=N with N a whole number from 1 to 64"),
    ("axis number 65", lambda d: ["compensate", "--fit", "fit.json", "--out", "comp", "--axis-number", "X=65"],
     r"from 1 to 64, got 'X=65'"),
    ("two axes one number", lambda d: ["compensate", "--fit", "fit.json", "--out", "comp", "--axis-number", "X=3", "C=3"],
     r"--axis-number gives axes 'X' and 'C' the same number 3"),
    ("plan grid counted before it is built", lambda d: PLAN + ["--marks-mm", "0", "0", "0"] + [
        f"--range={a}=-{h}:{h}:{2 * h / 9999}" for a, h in (("X", 100), ("Y", 100), ("B", 30), ("C", 180))] + ["--solve", "Z"],
     r"--range .*candidate alignments; at most 200,000"),
]



def _rows(d, n):
    lines = (d / "obs.csv").read_text(encoding="utf-8").splitlines()
    return _text(d, f"rows{n}.csv", "\n".join(lines[:n + 1]) + "\n")


_EXAMPLES = Path(__file__).resolve().parent.parent / "examples"

ROW_CASES = [
    ("identify one row, σ from residuals", lambda d: ["identify", "--machine", "m.urdf", "--data", _rows(d, 1), "--out", "f.json"],
     r"rows1\.csv: 1 observation row\(s\); a fit needs at least 2"),
    ("identify as many residuals as free parameters, σ from residuals",
     lambda d: ["identify", "--machine", str(_EXAMPLES / "../urdf/five_axis_bc.urdf"), "--data",
                str(_EXAMPLES / "observations.csv"), "--out", "f.json"],
     r"--noise-um is needed: 4 observation row\(s\) of .*observations\.csv give 12 residuals for 12 free parameters"),
    ("identify one row, σ given", lambda d: ["identify", "--machine", "m.urdf", "--data", _rows(d, 1), "--noise-um", "1", "--out", "f.json"],
     r"rows1\.csv: 1 observation row\(s\); a fit needs at least 2"),
    ("identify one row with a prior", lambda d: ["identify", "--machine", "m.urdf", "--data", _rows(d, 1), "--prior", "--out", "f.json"],
     r"rows1\.csv: 1 observation row\(s\); a fit needs at least 2"),
    ("verify two rows", lambda d: ["verify", "--fit", "fit.json", "--data", _rows(d, 2)],
     r"rows2\.csv: 2 observation row\(s\); a verification needs at least 3"),
    ("verify, first run of two rows", lambda d: ["verify", "--fit", "fit.json", "--data", "obs.csv", "--before", _rows(d, 2)],
     r"rows2\.csv: 2 observation row\(s\); a verification needs at least 3"),
    ("diagnose three rows", lambda d: ["diagnose", "--fit", "fit.json", "--data", _rows(d, 3)],
     r"rows3\.csv: 3 observation row\(s\); a diagnosis needs at least 4"),
    ("auto three rows", lambda d: ["identify", "--machine", "m.urdf", "--data", _rows(d, 3), "--auto", "--out", "f.json"],
     r"rows3\.csv: 3 observation row\(s\); a diagnosis needs at least 4"),
]

ALL = JSON_CASES + MODEL_CASES + NUMBER_CASES + ROW_CASES + PROMISE_CASES


@pytest.mark.parametrize("name, argv, expected", ALL, ids=[c[0] for c in ALL])
def test_bad_input_at_the_door(workdir, capsys, monkeypatch, name, argv, expected):  # noqa: F811
    refused_in(workdir, capsys, monkeypatch, name, argv, expected)


@pytest.mark.parametrize("names", [["j1", "j2", "j3"], ["joint1", "joint2"], ["elbow", "wrist"],
                                   ["shoulder_pan_joint", "elbow_joint"], ["J2", "shoulder"], ["X", "B"],
                                   ["a\u202eb", "c\x9bd"]])
def test_kinid_model_output_loads_back_with_every_joint_an_axis(tmp_path, capsys, names):
    """Whatever the source calls its joints, the machine written loads in kinid's own loader with exactly those
    joints as motion axes (a lower-case name once gave error joints EX0j1 read back as more axes), each axis
    name capitals and digits, the mapping printed with names escaped."""
    from kinid.identification import load_machine

    (tmp_path / "arm.urdf").write_text(_chain_urdf(names), encoding="utf-8")
    capsys.readouterr()
    assert main(["model", "--urdf", str(tmp_path / "arm.urdf"), "--tool", "flange",
                 "--out", str(tmp_path / "made.urdf")]) == 0
    out = capsys.readouterr().out
    machine = load_machine(str(tmp_path / "made.urdf"))
    assert [a.joint for a in machine.axes] == names
    assert len(machine.error_joints) == 6 * len(names) + 12
    for a in machine.axes:
        assert a.name.isalnum() and a.name.isupper() and a.name.isascii()
        assert a.name == a.joint or f"{a.name} ({a.joint if a.joint.isprintable() else repr(a.joint)})" in out
    assert len({a.name for a in machine.axes}) == len(names)
    assert out.isprintable() or all(line.isprintable() for line in out.splitlines())


def test_a_plan_too_small_to_determine_the_model_is_refused(tmp_path, capsys):
    """`plan --count 1` promised U = 0 µm (later 1.65e9 µm): a plan that leaves a parameter undetermined is refused,
    one line naming the count and the rank, nothing written."""
    from kinid.cli import main
    from kinid.urdf import path

    out = tmp_path / "plan.csv"
    assert main(["plan", "--machine", str(path("five_axis_bc")), "--count", "1", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--count" in err and "rank 3 of" in err and not out.exists()


def test_a_quoted_cell_over_two_lines_is_refused_naming_its_lines(tmp_path, capsys):
    """A quote left open swallowed the rows after it into one cell, and the file was read: now one line naming
    where the cell starts and ends, exit 2, no fit."""
    from kinid.cli import main
    from kinid.urdf import path

    obs = tmp_path / "obs.csv"
    obs.write_text('mark,wx_mm,wy_mm,wz_mm,x_mm,y_mm,z_mm,b_deg,c_deg\n'
                   '"M1\nM2",40,40,0,54.6,-40.0,54.6,-60,0\n'
                   'M3,-40,40,0,14.6,-40.0,-14.6,-60,0\n')
    assert main(["identify", "--machine", str(path("five_axis_bc")), "--data", str(obs), "--noise-um", "1",
                 "--out", str(tmp_path / "fit.json")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "obs.csv:2" in err and "lines 2 to 3" in err
    assert not (tmp_path / "fit.json").exists()
