"""The HTML report: provenance with checksums, identified errors with plain names and k = 2 uncertainties,
figures that exist, one unit style."""
from __future__ import annotations

import hashlib
import html
import re

import numpy as np
import pytest

from kinid.cli import main
from kinid.identification.model.names import plain_name
from kinid.urdf import path as urdf_path

MACHINE = str(urdf_path("five_axis_bc"))


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    d = tmp_path_factory.mktemp("report")
    (d / "errors.json").write_text('{"EX0C": 12.0, "EXX:periodic:10": [2.0, 1.0]}')
    assert main(["simulate", "--machine", MACHINE, "--errors", str(d / "errors.json"), "--noise-um", "1",
                 "--out", str(d / "obs.csv")]) == 0
    assert main(["identify", "--machine", MACHINE, "--data", str(d / "obs.csv"), "--add", "EXX:periodic:10",
                 "--noise-um", "1", "--out", str(d / "fit.json")]) == 0
    assert main(["diagnose", "--fit", str(d / "fit.json"), "--data", str(d / "obs.csv"), "--report", str(d / "rep")]) == 0
    return d, (d / "rep" / "index.html").read_text()


def _text(page):
    body = page[page.index("<body>"):]
    return re.sub(r"\s+", " ", html.unescape(re.sub(r"<[^>]+>", " ", body)))


def test_provenance_names_files_with_their_checksums(report):
    d, page = report
    text = _text(page)
    assert hashlib.sha256((d / "obs.csv").read_bytes()).hexdigest() in text
    assert hashlib.sha256((d / "fit.json").read_bytes()).hexdigest() in text
    assert hashlib.sha256(open(MACHINE, encoding="utf-8").read().encode()).hexdigest() in text
    assert "noise σ used" in text and "1 µm per coordinate (fit)" in text and "report made by kinid" in text
    assert re.search(r"made\s+\d{4}-\d\d-\d\d \d\d:\d\d:\d\d UTC", text)


def test_identified_errors_table(report):
    _, page = report
    rows = re.findall(r"<tr>(.*?)</tr>", page)
    cells = [[html.unescape(c) for c in re.findall(r"<td[^>]*>(.*?)</td>", r)] for r in rows]
    by_name = {c[0]: c for c in cells if c}
    sin = by_name["EXX:periodic:10[sin]"]
    assert sin[1] == "positioning error of X, sin term" and sin[5] == "µm"
    assert sin[2].startswith("periodic in X, period 10 mm; measured over X ")
    assert by_name["EXX:periodic:10[cos]"][1:3] == ["positioning error of X, cos term", "as above"]
    assert float(sin[3]) == pytest.approx(2.0, abs=0.5) and 0 < float(sin[4]) < 0.6  # U = 2σ
    assert by_name["EX0C"][1] == "position of the C axis line in X"
    assert by_name["EX0T"][3] == "held"


def test_summary_and_figures(report):
    d, page = report
    text = _text(page)
    assert "The model explains the data to the noise" in text and "move the tool point by up to" in text
    images = re.findall(r'<img src="([^"]+)"', page)
    assert {"errors.png", "residuals_binned.png", "measured_vs_model.png"} <= set(images)
    for name in images:
        assert (d / "rep" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_one_unit_style(report):
    _, page = report
    text = _text(page)
    assert not re.search(r"\d\s?um\b|\burad\b|\+-", text), re.findall(r".{30}(?:\d\s?um\b|\burad\b|\+-).{10}", text)[:3]


@pytest.mark.parametrize("code, name", [
    ("EXX", "positioning error of X"), ("EYX", "straightness of X in Y"), ("EAX", "roll of X"),
    ("ECC", "angular positioning error of C"), ("EXC", "radial motion of C in X"), ("EZC", "axial motion of C"),
    ("EAC", "tilt motion of C about X"), ("EC0Y", "squareness of Y about Z"), ("EX0C", "position of the C axis line in X"),
    ("EB0C", "tilt of the C axis line about Y"), ("EX0W", "workpiece (board) set-up offset in X"),
    ("EC0T", "tool (sensor) set-up rotation about Z"), ("XX", "XX"),
])
def test_plain_names(code, name):
    assert plain_name(code) == name


def test_each_position_dependent_error_says_what_part_of_its_travel_was_measured(report):
    """The range is read back against the data file and the URDF's limits, parsed here with the standard library."""
    import csv
    import xml.etree.ElementTree as ET

    d, page = report
    xs = [float(r["x_mm"]) for r in csv.DictReader(open(d / "obs.csv", encoding="utf-8"))]
    limit = next(j.find("limit") for j in ET.parse(MACHINE).getroot().iter("joint") if j.get("name") == "X")
    lo, hi = 1e3 * float(limit.get("lower")), 1e3 * float(limit.get("upper"))
    how = html.unescape(re.search(r"periodic in X, period 10 mm; (measured over [^<]*)<", page).group(1))
    m = re.fullmatch(r"measured over X (\S+) to (\S+) mm of its travel (\S+) to (\S+) mm \((\d+) %\)", how)
    assert m, how
    got = [float(v.replace("−", "-")) for v in m.groups()[:4]]
    assert got == pytest.approx([min(xs), max(xs), lo, hi], rel=1e-3, abs=0.05)
    assert int(m.group(5)) == round(100 * (max(xs) - min(xs)) / (hi - lo))


def test_the_report_is_also_one_pdf_of_a4_pages_holding_every_figure(report):
    d, page = report
    pdf = (d / "rep" / "report.pdf").read_bytes()
    assert pdf.startswith(b"%PDF-") and pdf.rstrip().endswith(b"%%EOF")
    boxes = re.findall(rb"/MediaBox \[\s*0 0 ([\d.]+) ([\d.]+)\s*\]", pdf)
    pages = len(re.findall(rb"/Type /Page\b", pdf))
    assert pages >= 3 and len(boxes) == pages
    assert all(abs(float(w) - 595.276) < 0.01 and abs(float(h) - 841.89) < 0.01 for w, h in boxes)  # A4
    shown = len(re.findall(r'<img src="([^"]+)"', page))
    assert len(re.findall(rb"/Subtype /Image", pdf)) >= shown > 0


def test_the_page_template_escapes_every_value_and_keeps_its_style():
    from kinid.reports.html import Section, Table, report_page

    page = report_page("a <b>", "s", [("file", "x<script>alert(1)</script>.csv")], ["it's \"quoted\""],
                       [Section("h&h", tables=(Table(("c",), (("<i>",),)),))])
    assert "<script>" not in page and "&lt;script&gt;" in page and "&lt;i&gt;" in page and "h&amp;h" in page
    assert 'font-family:-apple-system,"Segoe UI"' in page  # the style sheet is not escaped


def test_the_auto_report_shows_the_held_out_check_each_effect_passed(report, tmp_path, capsys):
    """identify --auto: the step table's held-out column is the selection's own check, before and after each
    effect, read back against the line the selection printed for it."""
    d, _ = report
    capsys.readouterr()
    assert main(["identify", "--machine", MACHINE, "--data", str(d / "obs.csv"), "--auto", "--noise-um", "1",
                 "--out", str(tmp_path / "auto.json"), "--report", str(tmp_path / "auto")]) == 0
    log = "".join(capsys.readouterr())
    said = re.findall(r"next: (\S+), p = \S+, held-out blocks \S+ \((\d+\.\d+) → (\d+\.\d+) µm", log)
    page = (tmp_path / "auto" / "index.html").read_text()
    table = page[page.index("The error falls"):page.index("Identified errors")]
    rows = [[html.unescape(c) for c in re.findall(r"<td[^>]*>(.*?)</td>", r)] for r in re.findall(r"<tr>(.*?)</tr>", table)]
    rows = [r for r in rows if r]
    assert "held-out RMS (µm)" in table and len(rows) >= 2 and len(said) >= len(rows) - 1, log
    assert rows[0][3] == said[0][1]  # the default model, before the first effect
    for row, (effect, _, after) in zip(rows[1:], said):
        assert row[1] == f"+ {effect}" and row[3] == after


def test_the_auto_report_does_not_advise_adding_what_the_selection_left_out(report, tmp_path):
    """A selection that stops with a significant candidate it did not add (here: no step allowed) says why, and
    its summary does not advise adding that candidate."""
    from kinid.identification import default_model, forward_select, load_machine
    from kinid.identification.data.observations import read_observations
    from kinid.identification.reporting.report import selection_report

    d, _ = report
    machine = load_machine(MACHINE)
    obs = read_observations(d / "obs.csv", machine)
    steps = forward_select(machine, obs, default_model(machine), noise_um=1.0, max_steps=0)
    best = steps[-1].diagnosis.live[0].effect
    assert steps[-1].diagnosis.live[0].p_value < steps[-1].diagnosis.threshold  # significant, and left out
    page = _text(selection_report(steps, obs, tmp_path / "rep").read_text())
    assert "Nothing was added: the default model stays" in page and "The error falls" not in page
    assert not (tmp_path / "rep" / "rms_steps.png").exists()  # no curve of a single point
    text = page.split("Nothing was added")[0]  # the summary
    assert f"--add {best}" not in text
    assert f"its most likely cause, {best}, was not added" in text and f"kinid plan --detect {best}=SIZE" in text
    assert f"{best} is significant" in text and "but was not added (stopped after 0 added effects" in text


def test_a_structured_residual_at_the_noise_is_told_as_such(tmp_path):
    """A lead of 0.5 µm under 1 µm of noise: the residual as a whole passes the χ² test against σ, yet the lead is
    significant. The summary does not say the residual exceeds the noise, and the candidates' caption states the
    level the threshold comes from (α over the candidates tested, the diagnosis's own figures)."""
    (tmp_path / "errors.json").write_text('{"EX0C": 12.0, "EXX:periodic:10": [0.5, 0.2]}')
    assert main(["simulate", "--machine", MACHINE, "--errors", str(tmp_path / "errors.json"), "--noise-um", "1",
                 "--out", str(tmp_path / "obs.csv")]) == 0
    assert main(["identify", "--machine", MACHINE, "--data", str(tmp_path / "obs.csv"), "--noise-um", "1",
                 "--out", str(tmp_path / "fit.json")]) == 0
    assert main(["diagnose", "--fit", str(tmp_path / "fit.json"), "--data", str(tmp_path / "obs.csv"),
                 "--report", str(tmp_path / "rep")]) == 0
    from kinid.identification import diagnose, load_fit
    from kinid.identification.diagnosis.diagnose import ALPHA
    from kinid.identification.data.observations import read_observations

    f = load_fit(tmp_path / "fit.json")
    dg = diagnose(f.machine, read_observations(tmp_path / "obs.csv", f.machine), f.effects, noise_um=1.0)
    assert dg.chi2_p > ALPHA and dg.live[0].effect == "EXX:periodic:10" and dg.live[0].p_value < dg.threshold
    text = _text((tmp_path / "rep" / "index.html").read_text())
    assert "near σ 1 µm) holds, beneath the noise, an effect the model lacks, most likely EXX:periodic:10" in text
    assert "shows an effect the model lacks" not in text
    assert f"p < {dg.threshold:.3g} (α = {ALPHA:g} over the {len(dg.live)} candidates tested)" in text
    assert dg.threshold == pytest.approx(ALPHA / len(dg.live))


def test_the_periodogram_is_scipys_lomb_scargle_for_every_component_at_once():
    """The report's periodogram (one set of sines for the three components) equals SciPy's, column by column, and
    puts a 10 mm lead's peak at 10 mm with the power A² N / 4 SciPy documents."""
    from scipy.signal import lombscargle

    from kinid.identification.reporting.figures import lomb_scargle_power

    rng = np.random.default_rng(3)
    x = rng.uniform(-70.0, 70.0, 336)
    y = rng.normal(0.0, 0.2, (336, 3))
    y[:, 1] += 2.5 * np.sin(2 * np.pi * x / 10.0 + 0.3)
    y -= y.mean(axis=0)
    periods = np.geomspace(1.0, 60.0, 600)
    w = 2 * np.pi / periods
    got = lomb_scargle_power(x, y, w)
    want = np.stack([lombscargle(x, y[:, c], w, normalize=False) for c in range(3)], axis=1)
    assert got.shape == (600, 3)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9 * want.max())
    assert periods[np.argmax(got[:, 1])] == pytest.approx(10.0, rel=0.01)
    assert got[:, 1].max() == pytest.approx(2.5 ** 2 * 336 / 4, rel=0.1)


def test_the_next_step_of_a_missing_effect_runs_as_written_from_where_the_user_stands(report, monkeypatch, capsys):
    """The summary's next command names the machine and the data as a command typed in the working folder takes
    them (relative paths, no '...'), and it runs: the fit it writes holds the effect advised."""
    import shlex

    d, _ = report
    monkeypatch.chdir(d)
    assert main(["identify", "--machine", MACHINE, "--data", "obs.csv", "--noise-um", "1", "--out", "fit0.json"]) == 0
    assert main(["diagnose", "--fit", "fit0.json", "--data", "obs.csv", "--report", "rep0"]) == 0
    text = _text((d / "rep0" / "index.html").read_text())
    command = re.search(r"next: (kinid identify .*? --out \S+\.json)\.", text)
    assert command, text[:2000]
    argv = shlex.split(command.group(1))
    assert "..." not in argv and argv[argv.index("--data") + 1] == "obs.csv"
    assert argv[argv.index("--noise-um") + 1] == "1"  # the σ the fit was made with, carried
    capsys.readouterr()
    assert main(argv[1:]) == 0
    from kinid.identification import load_fit

    added = argv[argv.index("--add") + 1]
    assert added in load_fit(d / argv[argv.index("--out") + 1]).effect_names
