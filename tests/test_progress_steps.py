"""A command's long steps say what they are doing on a terminal, and nothing elsewhere (kinid.progress.step)."""
from __future__ import annotations

import io
import time

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


def test_compensate_and_certificate_say_their_steps_on_a_terminal(tmp_path, monkeypatch, capsys):
    """Every step shown (STEP_SHOWN_S = 0): compensate's tables and checks, the certificate's pages."""
    import sys
    from pathlib import Path

    import kinid.progress
    from kinid.cli import main

    root = Path(__file__).resolve().parents[1]
    machine = str(root / "urdf" / "five_axis_bc.urdf")
    assert main(["simulate", "--machine", machine, "--errors", str(root / "examples" / "errors.json"), "--plan",
                 "patent", "--noise-um", "1", "--out", str(tmp_path / "obs.csv")]) == 0
    assert main(["identify", "--machine", machine, "--data", str(tmp_path / "obs.csv"), "--noise-um", "1", "--out",
                 str(tmp_path / "fit.json")]) == 0
    capsys.readouterr()
    monkeypatch.setattr(kinid.progress, "STEP_SHOWN_S", 0.0)
    for args, label in (
            (["compensate", "--fit", tmp_path / "fit.json", "--out", tmp_path / "comp"],
             f"writing the tables and checking each as its controller applies it ({tmp_path / 'comp'})"),
            (["certificate", "--fit", tmp_path / "fit.json", "--meta", root / "examples" / "certificate_meta.json",
              "--out", tmp_path / "cert"], f"writing the certificate to {tmp_path / 'cert'} (PDF and HTML)")):
        terminal = Terminal()
        monkeypatch.setattr(sys, "stderr", terminal)
        assert main([str(a) for a in args]) == 0
        shown = [line for line in terminal.getvalue().splitlines() if line.startswith(label)]
        assert shown[0] == f"{label} …" and shown[1].startswith(f"{label}: done in "), terminal.getvalue()
