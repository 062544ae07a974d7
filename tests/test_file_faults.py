"""Every file a verb writes, on a full disk or in a folder it may not write: one line, exit 2, the old file intact.

The (verb, option) pairs are every output its parser declares a file; each needs a working call in ``CALLS`` (a
verb or an output added without one fails :func:`test_every_file_output_has_a_call`). The faults are put in where
the file system would put them: the write of the output's temporary file fails with ENOSPC (a full disk; also at
the sync, where a full disk often shows first), or making that file fails with EACCES or EROFS (a folder the
user may not write, a read-only file system). The output exists beforehand with other bytes; afterwards it has
them still, and nothing else is left beside it. ``--json`` to a full standard output is one line too.
"""
from __future__ import annotations

import argparse
import errno
import os
import tempfile
from pathlib import Path

import pytest

from kinid.cli import DEFAULT_OUTPUTS, VERBS, build_parser, main
from kinid.urdf import path as urdf_path

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
RUN = EXAMPLES / "run"
MACHINE = str(urdf_path("five_axis_bc"))
OBS, FIT = "{d}/obs.csv", "{d}/fit.json"
MOVES, DUAL = str(EXAMPLES / "stages" / "uvw_moves.csv"), str(EXAMPLES / "stages" / "dual_axis.csv")
BACKLASH = str(EXAMPLES / "stages" / "backlash" / "log.csv")
PIXEL_TO_MM = ["0.0049931", "0.0002617", "0.0002617", "-0.0049931"]

#: A working call per file output (without the output option; ``{d}`` is the data folder).
CALLS = {
    ("plan", "--out"): ["plan", "--machine", MACHINE, "--count", "12"],
    ("simulate", "--out"): ["simulate", "--machine", MACHINE, "--errors", str(EXAMPLES / "errors.json")],
    ("identify", "--out"): ["identify", "--machine", MACHINE, "--data", OBS],
    ("predict", "--out"): ["predict", "--fit", FIT, "--poses", str(EXAMPLES / "poses.csv")],
    ("model", "--out"): ["model", "--urdf", str(EXAMPLES / "ur_like.urdf"), "--base", "world", "--tool",
                         "wrist_3_link"],
    ("sensor", "--out"): ["sensor", "--machine", MACHINE, "--hole", str(EXAMPLES / "sensor_hole.csv"), "--base",
                          str(RUN / "sensor.json")],
    ("observe", "--out"): ["observe", "--machine", MACHINE, "--board", str(RUN / "board.json"), "--sensor",
                           str(RUN / "sensor.json"), "--data", str(RUN / "log.csv")],
    ("board", "--out"): ["board", "--rows", "3", "--cols", "4"],
    ("board", "--svg"): ["board", "--rows", "3", "--cols", "4", "--out", "{d}/b_{u}.json"],
    ("board", "--pdf"): ["board", "--rows", "3", "--cols", "4", "--out", "{d}/b_{u}.json"],
    ("markers", "--draw"): ["markers", str(RUN / "images" / "000.png")],
    ("backlash", "--out"): ["backlash", "--data", BACKLASH, "--travel-mm", "0.4"],
    ("backlash", "--plot"): ["backlash", "--data", BACKLASH, "--travel-mm", "0.4"],
    ("backlash", "--plan-out"): ["backlash", "--travel-mm", "0.4"],
    ("uvw", "--out"): ["uvw", "--data", MOVES, "--lead-um", "2000"],
    ("uvw", "--plot"): ["uvw", "--data", MOVES, "--lead-um", "2000"],
    ("dual-axis", "--out"): ["dual-axis", "--data", DUAL, "--pixel-to-mm", *PIXEL_TO_MM],
    ("dual-axis", "--plot"): ["dual-axis", "--data", DUAL, "--pixel-to-mm", *PIXEL_TO_MM],
    ("contour", "--out"): ["contour", "--simulate", "--sim-frames", "12", "--workers", "1"],
    ("contour", "--plot"): ["contour", "--simulate", "--sim-frames", "12", "--workers", "1"],
    ("iso230-2", "--plot"): ["iso230-2", "--data", str(EXAMPLES / "x_runs.csv"), "--axis", "X"],
}


def _verb_parser(verb):
    parser = build_parser(verb)
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[verb]


def file_outputs() -> set:
    out = set()
    for verb in VERBS:
        sub = _verb_parser(verb)
        outputs = sub.get_default("outputs") or DEFAULT_OUTPUTS
        out |= {(verb, a.option_strings[-1]) for a in sub._actions
                if a.option_strings and outputs.get(a.dest) == "file"}
    return out


def test_every_file_output_has_a_call():
    declared = file_outputs()
    assert declared == set(CALLS), f"file outputs without a call: {sorted(declared - set(CALLS))}; " \
                                   f"calls of no file output: {sorted(set(CALLS) - declared)}"


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    d = tmp_path_factory.mktemp("file_faults")
    assert main(["simulate", "--machine", MACHINE, "--errors", str(EXAMPLES / "errors.json"), "--noise-um", "1",
                 "--seed", "5", "--out", str(d / "obs.csv")]) == 0
    assert main(["identify", "--machine", MACHINE, "--data", str(d / "obs.csv"), "--out", str(d / "fit.json")]) == 0
    return d


def _suffix(option: str, case) -> str:
    if option in ("--plot", "--draw"):
        return ".png"
    return {"--svg": ".svg", "--pdf": ".pdf", "--plan-out": ".csv"}.get(option, {
        "plan": ".csv", "simulate": ".csv", "predict": ".csv", "observe": ".csv", "dual-axis": ".csv",
        "contour": ".csv", "model": ".urdf"}.get(case[0], ".json"))


FAULTS = [("write", errno.ENOSPC), ("sync", errno.ENOSPC), ("create", errno.EACCES), ("create", errno.EROFS)]


@pytest.mark.parametrize("fault, code", FAULTS, ids=lambda v: v if isinstance(v, str) else errno.errorcode[v])
@pytest.mark.parametrize("case", sorted(CALLS), ids=lambda c: f"{c[0]} {c[1]}")
def test_a_failed_write_is_one_line_and_the_old_file_stays(data, case, fault, code, tmp_path, monkeypatch, capsys):
    out = tmp_path / f"out{_suffix(case[1], case)}"
    out.write_bytes(b"the earlier output\n")
    argv = [a.replace("{d}", str(data)).replace("{u}", tmp_path.name) for a in CALLS[case]] + [case[1], str(out)]
    _inject(monkeypatch, out, fault, code)
    status = main(argv)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip() and ": warning: " not in line]  # the data's own
    assert status == 2 and len(lines) == 1 and "Traceback" not in err, (case, fault, status, err)
    assert lines[0].startswith(f"kinid {case[0]}: ") and out.name in lines[0], lines[0]
    assert os.strerror(code) in lines[0], (case, fault, lines[0])
    assert out.read_bytes() == b"the earlier output\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == [out.name], sorted(p.name for p in tmp_path.iterdir())


def _inject(monkeypatch, out: Path, fault: str, code: int) -> None:
    """Make the output's temporary file (made by kinid.files.atomic_write beside ``out``) fail."""
    prefix = f".{out.name}."
    mkstemp, fdopen, fsync = tempfile.mkstemp, os.fdopen, os.fsync
    ours = set()

    def fake_mkstemp(*args, **kwargs):
        if kwargs.get("prefix") == prefix and fault == "create":
            raise OSError(code, os.strerror(code), str(out.parent))
        fd, name = mkstemp(*args, **kwargs)
        if kwargs.get("prefix") == prefix:
            ours.add(fd)
        return fd, name

    class Full:
        def __init__(self, f):
            self._f = f

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self._f.close()
            return False

        def write(self, data):
            raise OSError(code, os.strerror(code))

        def __getattr__(self, name):
            return getattr(self._f, name)

    def fake_fdopen(fd, *args, **kwargs):
        f = fdopen(fd, *args, **kwargs)
        return Full(f) if fd in ours and fault == "write" else f

    def fake_fsync(fd):
        if fd in ours and fault == "sync":
            raise OSError(code, os.strerror(code))
        return fsync(fd)

    monkeypatch.setattr(tempfile, "mkstemp", fake_mkstemp)
    monkeypatch.setattr(os, "fdopen", fake_fdopen)
    monkeypatch.setattr(os, "fsync", fake_fsync)


@pytest.mark.parametrize("argv", [
    ["uvw", "--data", MOVES, "--lead-um", "2000", "--json"],
    ["iso230-2", "--data", str(EXAMPLES / "x_runs.csv"), "--axis", "X", "--json"],
    ["diagnose", "--fit", FIT, "--data", OBS, "--json"],
], ids=lambda a: a[0])
def test_json_to_a_full_standard_output_is_one_line(data, argv, capsys, monkeypatch):
    """``kinid VERB --json > file`` on a full disk: the print fails with ENOSPC; one line on stderr, exit 2."""
    import io
    import sys

    class FullStdout(io.StringIO):
        def write(self, text):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    argv = [a.replace("{d}", str(data)) for a in argv]
    monkeypatch.setattr(sys, "stdout", FullStdout())
    status = main(argv)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert status == 2 and len(lines) == 1 and "No space left on device" in lines[0], (status, err)
