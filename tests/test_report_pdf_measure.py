"""The report's PDF lays its text out as measuring every trial line whole would: its wrap predicts a line's width
from its words' (kinid.reports.pdf), and these tests compare that with the plain greedy rule measured line by line."""
import numpy as np
import pytest

from kinid.reports.pdf import _Flow, _font

#: Words of a report's sentences: kerning pairs (AV, Te, y.), µ, σ, ±, quotes, numbers, a SHA-256 longer than a line.
WORDS = ("AVAILABLE", "Te", "y.", "(σ", "1.37", "µm", "±2σ", "“held”", "EXX:periodic:10", "workpiece,", "−0.25",
         "W/T", "f" * 3, "fi", "L'", "7.5", "ÉCART", "the", "a", "of", "3f6a" * 16, "rotary", "X —", "—")


def _greedy(flow, text, size, width_pt, weight):
    """Lines of ``text``: each the longest run of words whose whole line, measured, fits ``width_pt``."""
    lines = []
    for paragraph in text.split("\n"):
        line = ""
        for word in paragraph.split(" "):
            trial = f"{line} {word}" if line else word
            if flow._width(trial, size, weight) <= width_pt:
                line = trial
                continue
            if line:
                lines.append(line)
            while flow._width(word, size, weight) > width_pt and len(word) > 1:
                cut = max(1, int(len(word) * width_pt / flow._width(word, size, weight)) - 1)
                lines.append(word[:cut])
                word = word[cut:]
            line = word
        lines.append(line)
    return lines


@pytest.mark.parametrize("seed", range(3))
def test_wrap_breaks_lines_as_measuring_each_whole_line(seed):
    rng = np.random.default_rng(seed)
    flow = _Flow()
    for _ in range(10):
        text = " ".join(rng.choice(WORDS, size=rng.integers(1, 40)))
        text = text.replace(" the ", "\n", 1) if rng.random() < 0.3 else text  # paragraphs, and a double space
        text = text.replace(" a ", "  a ", 1)
        size = float(rng.choice([7.5, 8.0, 9.5, 10.0]))
        weight = str(rng.choice(["normal", "bold"]))
        width_pt = float(rng.uniform(40, 480))
        assert flow.wrap(text, size, width_pt, weight) == _greedy(flow, text, size, width_pt, weight), (text, width_pt)


def test_wrap_agrees_at_the_limit():
    # a line exactly as wide as the limit stays one line; a hundredth of a point less breaks it
    flow = _Flow()
    text = "The residual holds, beneath the noise, an effect the model lacks"
    full = flow._width(text, 9.5)
    assert flow.wrap(text, 9.5, full) == [text]
    assert len(flow.wrap(text, 9.5, full - 0.01)) == 2
    assert flow.wrap(text, 9.5, full - 0.01) == _greedy(flow, text, 9.5, full - 0.01, "normal")


@pytest.mark.parametrize("seed", range(2))
def test_a_line_is_placed_with_the_height_and_descent_of_measuring_it_whole(seed):
    """_put places a line from its characters' boxes (kinid.reports.pdf._Flow._height_descent), not by shaping it:
    the same height and descent as the whole line measured, in both fonts, with the text output's no-break spaces."""
    rng = np.random.default_rng(seed)
    flow = _Flow()
    extra = ("(Å)", "|x|", "[−3]", "g_q", "µ²", "\u00a0\u00a0", "…", "ŷ")
    for _ in range(40):
        text = " ".join(rng.choice(WORDS + extra, size=rng.integers(1, 12)))
        family = str(rng.choice(["sans-serif", "monospace"]))
        text = text.replace(" ", "\u00a0") if family == "monospace" else text
        size, weight = float(rng.choice([6.5, 7.5, 9.5, 13.0])), str(rng.choice(["normal", "bold"]))
        whole = flow._measure.get_text_width_height_descent(text, _font(size, weight, family), False)
        assert flow._height_descent(text, size, weight, family) == pytest.approx(whole[1:], abs=1e-9), text
    assert flow._height_descent(" ", 9.5) == pytest.approx(flow._metric(" ", 9.5)[1:])
