"""A command's long steps say what they are doing on a terminal, and nothing elsewhere (kinid.progress.step)."""
from __future__ import annotations

import io
import sys
import time
from pathlib import Path

import pytest

import kinid.progress
from kinid.cli import main
from kinid.progress import step


class Terminal(io.StringIO):
    def isatty(self):
        return True


def test_a_long_step_says_its_label_and_its_time_on_a_terminal():
    out = Terminal()
    with step("fitting 336 alignments", stream=out, after_s=0.05):
        time.sleep(0.3)
    lines = out.getvalue().splitlines()
    assert lines[0] == "fitting 336 alignments …"
    assert lines[1].startswith("fitting 336 alignments: done in ") and lines[1].endswith(" s")
    assert float(lines[1].split("done in ")[1][:-2]) >= 0.3


def test_a_quick_step_and_a_step_on_a_file_say_nothing():
    out = Terminal()
    with step("quick", stream=out, after_s=0.5):
        pass
    time.sleep(0.6)  # the timer, cancelled, never writes
    assert out.getvalue() == ""
    file = io.StringIO()
    with step("long", stream=file, after_s=0.0):
        time.sleep(0.1)
    assert file.getvalue() == ""


def test_a_step_ended_by_an_error_says_where_it_stopped():
    out = Terminal()
    try:
        with step("checking", stream=out, after_s=0.02):
            time.sleep(0.1)
            raise ValueError("stop")
    except ValueError:
        pass
    assert out.getvalue().splitlines()[-1].startswith("checking: stopped after ")


ROOT = Path(__file__).resolve().parents[1]
MACHINE = str(ROOT / "urdf" / "five_axis_bc.urdf")


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    d = tmp_path_factory.mktemp("steps")
    assert main(["simulate", "--machine", MACHINE, "--errors", str(ROOT / "examples" / "errors.json"), "--plan",
                 "patent", "--noise-um", "1", "--out", str(d / "obs.csv")]) == 0
    assert main(["identify", "--machine", MACHINE, "--data", str(d / "obs.csv"), "--noise-um", "1", "--out",
                 str(d / "fit.json")]) == 0
    return d


def _steps_said(args, label, monkeypatch):
    """The lines of ``label`` on a terminal-like stderr with every step shown (STEP_SHOWN_S = 0)."""
    monkeypatch.setattr(kinid.progress, "STEP_SHOWN_S", 0.0)
    terminal = Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    assert main([str(a) for a in args]) == 0
    monkeypatch.undo()
    return [line for line in terminal.getvalue().splitlines() if line.startswith(label)], terminal.getvalue()


@pytest.mark.parametrize("verb", ["identify", "diagnose", "compensate", "certificate"])
def test_the_long_steps_of_each_verb_are_said_on_a_terminal(fitted, tmp_path, monkeypatch, capsys, verb):
    """identify's fit, diagnose's scoring, compensate's tables and checks, the certificate's pages."""
    d = fitted
    args, label = {
        "identify": (["identify", "--machine", MACHINE, "--data", d / "obs.csv", "--noise-um", "1", "--out",
                      tmp_path / "fit.json"], "fitting 336 alignments"),
        "diagnose": (["diagnose", "--fit", d / "fit.json", "--data", d / "obs.csv"],
                     "scoring the candidate effects against the residual of 336 alignments"),
        "compensate": (["compensate", "--fit", d / "fit.json", "--out", tmp_path / "comp"],
                       f"writing the tables and checking each as its controller applies it ({tmp_path / 'comp'})"),
        "certificate": (["certificate", "--fit", d / "fit.json", "--meta", ROOT / "examples" / "certificate_meta.json",
                         "--out", tmp_path / "cert"], f"writing the certificate to {tmp_path / 'cert'} (PDF and HTML)"),
    }[verb]
    shown, said = _steps_said(args, label, monkeypatch)
    assert shown[0] == f"{label} …" and shown[1].startswith(f"{label}: done in "), said


def test_auto_says_each_selection_step_on_a_terminal(fitted, tmp_path, monkeypatch, capsys):
    shown, said = _steps_said(["identify", "--machine", MACHINE, "--data", fitted / "obs.csv", "--noise-um", "1",
                               "--auto", "--out", tmp_path / "fit.json"], "  fitting the model", monkeypatch)
    assert shown[0] == "  fitting the model and scoring the candidates (step 1) …", said
