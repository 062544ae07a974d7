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
