"""``kinid contour --simulate``: a rendered run measured like real frames, against its truth; the kept frames
measure the same through the ordinary command."""
from __future__ import annotations

import json

from kinid.cli import main


def test_simulate_reports_measured_against_true_and_keeps_the_frames(tmp_path, capsys):
    assert main(["contour", "--simulate", "--sim-frames", "24", "--json", "--keep", str(tmp_path / "run"),
                 "--out", str(tmp_path / "sim.csv")]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["located"] == s["frames"] == 24
    assert s["track_rms_error_um"] < 0.5
    assert abs(s["contour_rms_um"] - s["true_contour_rms_um"]) < 0.1 and s["true_contour_rms_um"] > 1.0
    run = tmp_path / "run"
    assert main(["contour", "--data", str(run / "frames"), "--board", str(run / "board.json"), "--camera",
                 str(run / "camera.json"), "--out", str(tmp_path / "real.csv")]) == 0
    rows = lambda p: [ln.split(",")[2:4] for ln in p.read_text().splitlines()[1:]]  # noqa: E731
    assert rows(tmp_path / "real.csv") == rows(tmp_path / "sim.csv")


def test_measured_frames_need_their_inputs(capsys):
    assert main(["contour", "--data", "x"]) == 2
    assert "measured frames need --board, --out, --pixel-um or --camera" in capsys.readouterr().err


def test_contour_report(tmp_path, capsys):
    assert main(["contour", "--simulate", "--sim-frames", "16", "--report", str(tmp_path / "rep")]) == 0
    page = (tmp_path / "rep" / "index.html").read_text()
    assert "<h1>Contour error</h1>" in page and "ISO 230-4 circular deviation G" in page
    assert "rendered by --simulate" in page and (tmp_path / "rep" / "contour.png").read_bytes()[:4] == b"\x89PNG"


def test_simulate_measures_against_the_radius_given(tmp_path, capsys):
    """--radius with --simulate is the nominal circle (it was ignored, and the report then stated the fitted radius
    as the nominal R0 without saying it was fitted); --simulate with a path other than a circle is refused."""
    assert main(["contour", "--simulate", "--sim-frames", "16", "--radius-mm", "8.05", "--report", str(tmp_path / "rep")]) == 0
    page = (tmp_path / "rep" / "index.html").read_text()
    assert "nominal radius R0</td><td>8.0500 mm</td>" in page
    capsys.readouterr()
    assert main(["contour", "--simulate", "--path", "line"]) == 2
    assert "--simulate renders a circular run" in capsys.readouterr().err


def test_simulate_leaves_no_temporary_folder_however_it_ends(tmp_path, monkeypatch, capsys):
    """Without --keep the frames are rendered in a temporary folder: removed after a run that succeeds and after one
    that fails once the frames are rendered (an output that cannot be written); such folders were left behind."""
    import tempfile

    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))  # (multiprocessing's own pymp-* folder may appear)
    assert main(["contour", "--simulate", "--sim-frames", "8", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["frames"] == 8
    assert list(scratch.glob("kinid-*")) == []
    blocked = tmp_path / "a_file"
    blocked.write_text("not a folder")
    assert main(["contour", "--simulate", "--sim-frames", "8", "--out", str(blocked / "track.csv")]) == 2
    assert "track.csv" in capsys.readouterr().err
    assert list(scratch.glob("kinid-*")) == []
