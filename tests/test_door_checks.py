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


@pytest.mark.parametrize("name, argv, expected", JSON_CASES + MODEL_CASES,
                         ids=[c[0] for c in JSON_CASES + MODEL_CASES])
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
