"""Every ``--json`` output is strict JSON (a NaN or infinity is ``null``, never ``NaN``/``Infinity``); the JSON
files kinid writes hold no non-finite number; a ``--report DIR`` folder is written whole or not at all and
replaces only an empty folder or an earlier kinid report.

Where a non-finite number cannot be provoked cheaply, the command's result is monkeypatched to hold one: the
test is of the printer, not of the computation.
"""
from __future__ import annotations

import dataclasses
import importlib
import json
import math
import os
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from kinid.cli import main
from kinid.urdf import path as urdf_path

MACHINE = str(urdf_path("five_axis_bc"))
EX = Path(__file__).resolve().parent.parent / "examples" / "stages"
NAN, INF = float("nan"), float("inf")


def _strict(text):
    """``text`` parsed as JSON; NaN, Infinity or -Infinity in it fail the test."""
    def refuse(name):
        raise AssertionError(f"not strict JSON: {name} in {text[:200]!r}")

    return json.loads(text, parse_constant=refuse)


def _snapshot(folder: Path) -> dict:
    """name -> bytes of every entry of ``folder`` (sub-folders as a marker)."""
    return {p.name: (p.read_bytes() if p.is_file() else "<dir>") for p in sorted(folder.iterdir())}


def _leftovers(folder: Path) -> list:
    """What staged writing left beside ``folder`` (lock, new or old folders)."""
    return sorted(p.name for p in folder.parent.iterdir() if p.name.startswith(f".{folder.name}.kinid-"))


def _foreign(tmp_path) -> Path:
    """A folder of the user's own files."""
    d = tmp_path / "mine"
    d.mkdir()
    (d / "notes.txt").write_text("my notes\n")
    (d / "photo.png").write_bytes(b"\x89PNG not really")
    return d


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A simulated run of the B/C machine and its fit (about two seconds)."""
    d = tmp_path_factory.mktemp("strict")
    (d / "errors.json").write_text('{"EX0C": 12.0, "EXX:periodic:10": [2.0, 1.0]}')
    assert main(["simulate", "--machine", MACHINE, "--errors", str(d / "errors.json"), "--noise-um", "1",
                 "--out", str(d / "obs.csv")]) == 0
    assert main(["identify", "--machine", MACHINE, "--data", str(d / "obs.csv"), "--add", "EXX:periodic:10",
                 "--noise-um", "1", "--no-robust", "--out", str(d / "fit.json")]) == 0
    return d


# --- every --json printer -----------------------------------------------------------------------------

def test_diagnose_json(run, monkeypatch, capsys):
    module = importlib.import_module("kinid.identification.diagnosis.diagnose")

    real = module.diagnose
    monkeypatch.setattr(module, "diagnose", lambda *a, **k: dataclasses.replace(real(*a, **k), rms_um=NAN))
    capsys.readouterr()
    assert main(["diagnose", "--fit", str(run / "fit.json"), "--data", str(run / "obs.csv"), "--json"]) == 0
    out = _strict(capsys.readouterr().out)
    assert out["rms_um"] is None and out["noise_um"] == 1.0 and out["verdict"]


def test_verify_json(run, monkeypatch, capsys):
    module = importlib.import_module("kinid.identification.compensation.verify")

    monkeypatch.setattr(module, "verify", lambda *a, **k: SimpleNamespace(summary=lambda: {
        "before_um": {"3d": INF}, "after_um": {"3d": np.float64("nan")}, "chi2_p": NAN, "n_observations": 3}))
    assert main(["verify", "--fit", str(run / "fit.json"), "--data", str(run / "obs.csv"), "--json"]) == 0
    out = _strict(capsys.readouterr().out)
    assert out == {"before_um": {"3d": None}, "after_um": {"3d": None}, "chi2_p": None, "n_observations": 3}


def test_uvw_measured_json(monkeypatch, capsys):
    module = importlib.import_module("kinid.stages.uvw.measured")

    real = module.models_json

    def with_nan(models, source):
        doc = real(models, source)
        first = next(iter(doc["actuators"].values()))
        first["rms_um"], first["noise_um"] = NAN, -INF
        return doc

    monkeypatch.setattr(module, "models_json", with_nan)
    assert main(["uvw", "--data", str(EX / "uvw_moves.csv"), "--json"]) == 0
    out = _strict(capsys.readouterr().out)
    first = next(iter(out["actuators"].values()))
    assert first["rms_um"] is None and first["noise_um"] is None and first["parameters"]


def test_uvw_simulate_json(monkeypatch, capsys):
    module = importlib.import_module("kinid.stages.uvw.demo")

    monkeypatch.setattr(module, "run_demo", lambda **k: {"validation": {"all": {"model": {"max_um": NAN}}},
                                                         "series": np.array([1.0, INF]), "_private": object()})
    assert main(["uvw", "--simulate", "--json"]) == 0
    assert _strict(capsys.readouterr().out) == {"validation": {"all": {"model": {"max_um": None}}},
                                                "series": [1.0, None]}


def test_contour_simulate_json(monkeypatch, capsys):
    importlib.import_module("kinid.stages.contour.measure")  # binds the real contour_error before the patch
    paths = importlib.import_module("kinid.stages.contour.paths")

    real = paths.contour_error
    monkeypatch.setattr(paths, "contour_error",
                        lambda *a, **k: dataclasses.replace(real(*a, **k), rms_um=NAN, max_um=INF))
    assert main(["contour", "--simulate", "--sim-frames", "8", "--workers", "1", "--json"]) == 0
    out = _strict(capsys.readouterr().out)
    assert out["true_contour_rms_um"] is None and out["true_contour_max_um"] is None
    assert out["located"] == out["frames"] == 8 and math.isfinite(out["contour_rms_um"])


def test_contour_measured_json(tmp_path, monkeypatch, capsys):
    import kinid.vision
    frames = importlib.import_module("kinid.stages.contour.frames")
    measure = importlib.import_module("kinid.stages.contour.measure")

    fake = SimpleNamespace(summary={"frames": 2, "located": 0, "rms_error_um": NAN, "max_error_um": INF},
                           track=SimpleNamespace(not_located=[]), fps=10.0)
    monkeypatch.setattr(kinid.vision, "load_board", lambda path: SimpleNamespace(bits=12))
    monkeypatch.setattr(frames, "open_frames", lambda path: SimpleNamespace(count=2))
    monkeypatch.setattr(measure, "measure_contour", lambda *a, **k: fake)
    monkeypatch.setattr(measure, "track_csv", lambda m: "frame,t_s,x_mm,y_mm,error_um\n")
    (tmp_path / "frames").mkdir()  # the track is written beside the frames, never among them
    assert main(["contour", "--data", str(tmp_path / "frames"), "--board", str(tmp_path / "board.json"), "--pixel-um",
                 "10", "--out", str(tmp_path / "track.csv"), "--json"]) == 0
    assert _strict(capsys.readouterr().out) == {"frames": 2, "located": 0, "rms_error_um": None,
                                                "max_error_um": None}


def test_backlash_json(monkeypatch, capsys):
    module = importlib.import_module("kinid.stages.backlash.calibrate")

    monkeypatch.setattr(module, "calibrate", lambda *a, **k: SimpleNamespace(
        summary=lambda: {"backlash_x_um": NAN, "spread_x_um": INF, "moves": 21}))
    assert main(["backlash", "--simulate", "--json"]) == 0
    out = _strict(capsys.readouterr().out)
    assert out["measured"] == {"backlash_x_um": None, "spread_x_um": None, "moves": 21}
    assert out["errors"]["backlash_x_um"] is None and out["truth"]["backlash_x_um"] > 0


def test_markers_json(tmp_path, monkeypatch, capsys):
    import cv2

    ringcode = importlib.import_module("kinid.vision.ringcode")

    cv2.imwrite(str(tmp_path / "img.png"), np.full((16, 16), 128, np.uint8))
    monkeypatch.setattr(ringcode, "detect_markers", lambda img, **k: [
        SimpleNamespace(code=7, x_px=NAN, y_px=INF), SimpleNamespace(code=8, x_px=1.5, y_px=np.float64(2.5))])
    assert main(["markers", str(tmp_path / "img.png"), "--json"]) == 0
    assert _strict(capsys.readouterr().out) == [{"code": 7, "x_px": None, "y_px": None},
                                                {"code": 8, "x_px": 1.5, "y_px": 2.5}]


# --- JSON files: a non-finite number is a clear error (sensor) or null where null means "not known" ---

def test_sensor_file_with_a_non_finite_offset_is_an_error(tmp_path, monkeypatch, capsys):
    sensor_cli = importlib.import_module("kinid.identification.data.laser_offset")  # the module the verb calls

    (tmp_path / "hole.csv").write_text("role,x_mm,y_mm,z_mm,b_deg,c_deg\ncamera,0,0,0,0,0\nlaser,18,0,0,0,0\n")
    monkeypatch.setattr(sensor_cli, "laser_offset", lambda *a, **k: (
        np.array([NAN, 1.0]), np.array([0.01, 0.01]), SimpleNamespace(n_points=2)))
    assert main(["sensor", "--machine", MACHINE, "--hole", str(tmp_path / "hole.csv"), "--out",
                 str(tmp_path / "s.json")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "s.json" in err and "non-finite" in err
    assert not (tmp_path / "s.json").exists() and not list(tmp_path.glob(".s.json.*"))


def test_camera_file_is_strict(tmp_path):
    from kinid.errors import DataError
    from kinid.vision.camera import CameraModel, load_camera, save_camera

    cam = CameraModel(np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]]), np.zeros(5), (640, 480), INF)
    save_camera(cam, tmp_path / "camera.json")
    data = _strict((tmp_path / "camera.json").read_text())
    assert data["rms_px"] is None and data["camera_matrix"][0][0] == 500.0
    assert math.isnan(load_camera(tmp_path / "camera.json").rms_px)
    broken = SimpleNamespace(to_dict=lambda: {"camera_matrix": [[NAN]], "dist_coeffs": [], "image_size": [1, 1],
                                              "rms_px": None})
    with pytest.raises(DataError, match="non-finite"):
        save_camera(broken, tmp_path / "broken.json")
    assert not (tmp_path / "broken.json").exists()


# --- report folders: whole or not at all, never over the user's files ---------------------------------

UVW = ["uvw", "--data", str(EX / "uvw_moves.csv")]


def test_report_into_a_folder_of_other_files_is_refused(tmp_path, capsys):
    mine = _foreign(tmp_path)
    before = _snapshot(mine)
    assert main([*UVW, "--report", str(mine)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "mine" in err and "notes.txt" in err and "not an earlier result" in err
    assert _snapshot(mine) == before and not _leftovers(mine)


def test_report_replaces_an_earlier_report_whole(tmp_path, capsys):
    from kinid.files import write_text
    from kinid.reports.html import report_folder, report_page

    rep = tmp_path / "rep"
    with report_folder(rep) as stage:  # an earlier report with a figure the next one does not make
        (stage / "old_figure.png").write_bytes(b"\x89PNG old")
        write_text(stage / "index.html", report_page("Earlier test report", "kinid test", [], [], []))
    assert sorted(os.listdir(rep)) == ["index.html", "old_figure.png"]
    assert main([*UVW, "--report", str(rep)]) == 0
    assert sorted(os.listdir(rep)) == ["actuators.png", "index.html", "report.html", "report.pdf"]
    page = (rep / "index.html").read_text()
    assert "<h1>UVW stage: actuator error models</h1>" in page and "Earlier test report" not in page
    assert not _leftovers(rep)
    # and an earlier report of this command, again
    assert main([*UVW, "--report", str(rep)]) == 0
    assert sorted(os.listdir(rep)) == ["actuators.png", "index.html", "report.html", "report.pdf"] and not _leftovers(rep)


def test_interrupted_report_leaves_the_earlier_one_byte_for_byte(tmp_path, monkeypatch, capsys):
    module = importlib.import_module("kinid.stages.uvw.report")

    rep = tmp_path / "rep"
    assert main([*UVW, "--report", str(rep)]) == 0
    before = _snapshot(rep)

    def interrupted(models, path):
        Path(path).write_bytes(b"half a figure")
        raise KeyboardInterrupt

    monkeypatch.setattr(module, "plot_measured", interrupted)
    assert main([*UVW, "--report", str(rep)]) == 130
    assert "interrupted" in capsys.readouterr().err
    assert _snapshot(rep) == before and not _leftovers(rep)


def test_a_report_folder_may_not_hold_an_input(tmp_path, capsys):
    rep = tmp_path / "rep"
    rep.mkdir()
    (rep / "moves.csv").write_bytes((EX / "uvw_moves.csv").read_bytes())
    assert main(["uvw", "--data", str(rep / "moves.csv"), "--report", str(rep)]) == 2
    assert "moves.csv" in capsys.readouterr().err
    assert sorted(os.listdir(rep)) == ["moves.csv"]


@pytest.mark.parametrize("argv, module, work", [
    (["backlash", "--data", str(EX / "backlash" / "log.csv"), "--travel-mm", "0.4"], "kinid.stages.backlash.calibrate",
     "calibrate"),
    (["contour", "--simulate", "--sim-frames", "8"], "kinid.stages.contour.simulate", "render_sequence"),
    (["uvw", "--data", str(EX / "uvw_moves.csv")], "kinid.stages.uvw.measured", "fit_moves"),
], ids=["backlash", "contour", "uvw"])
def test_stage_reports_refuse_other_files_before_their_work(argv, module, work, tmp_path, monkeypatch, capsys):
    mine = _foreign(tmp_path)
    before = _snapshot(mine)
    monkeypatch.setattr(importlib.import_module(module), work,
                        lambda *a, **k: pytest.fail("the work was done before the folder was refused"))
    assert main([*argv, "--report", str(mine)]) == 2
    assert "not an earlier result" in capsys.readouterr().err
    assert _snapshot(mine) == before and not _leftovers(mine)


def test_backlash_and_contour_reports_are_written_whole(tmp_path, capsys):
    for argv, figure in ((["backlash", "--data", str(EX / "backlash" / "log.csv"), "--travel-mm", "0.4"],
                          "backlash.png"),
                         (["contour", "--simulate", "--sim-frames", "8", "--workers", "1"], "contour.png")):
        rep = tmp_path / argv[0]
        for _ in range(2):  # the second replaces the first
            assert main([*argv, "--report", str(rep)]) == 0
            assert sorted(os.listdir(rep)) == [figure, "index.html", "report.html", "report.pdf"] and not _leftovers(rep)
        assert "kinid-report-files" in (rep / "index.html").read_text()


def test_diagnose_report_refused_replaced_and_interrupted(run, tmp_path, monkeypatch, capsys):
    module = importlib.import_module("kinid.identification.reporting.report")

    argv = ["diagnose", "--fit", str(run / "fit.json"), "--data", str(run / "obs.csv"), "--report"]
    mine = _foreign(tmp_path)
    before = _snapshot(mine)
    assert main([*argv, str(mine)]) == 2
    assert "not an earlier result" in capsys.readouterr().err
    assert _snapshot(mine) == before and not _leftovers(mine)

    rep = tmp_path / "rep"
    assert main([*argv, str(rep)]) == 0
    first = _snapshot(rep)
    assert {"index.html", "residuals.csv", "periodogram.png"} <= set(first)

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    with monkeypatch.context() as m:
        m.setattr(module, "plot_periodogram", interrupted)
        assert main([*argv, str(rep)]) == 130
    assert _snapshot(rep) == first and not _leftovers(rep)

    assert main([*argv, str(rep)]) == 0  # an earlier report is replaced
    assert set(_snapshot(rep)) == set(first) and not _leftovers(rep)


def test_identify_report_refuses_other_files_and_writes_no_fit(run, tmp_path, capsys):
    mine = _foreign(tmp_path)
    before = _snapshot(mine)
    assert main(["identify", "--machine", MACHINE, "--data", str(run / "obs.csv"), "--noise-um", "1",
                 "--report", str(mine), "--out", str(tmp_path / "f.json")]) == 2
    assert "not an earlier result" in capsys.readouterr().err
    assert _snapshot(mine) == before and not _leftovers(mine) and not (tmp_path / "f.json").exists()


def test_selection_report_is_whole_except_for_the_demo(tmp_path):
    from kinid.errors import DataError
    from kinid.identification.reporting.report import selection_report

    mine = _foreign(tmp_path)
    before = _snapshot(mine)
    with pytest.raises(DataError, match="not an earlier result"):
        selection_report([], None, mine)  # refused before anything is made
    assert _snapshot(mine) == before and not _leftovers(mine)


def test_verify_report_refused_early_replaced_and_interrupted(run, tmp_path, monkeypatch, capsys):
    verify_module = importlib.import_module("kinid.identification.compensation.verify")
    module = importlib.import_module("kinid.identification.compensation.verify_report")

    argv = ["verify", "--fit", str(run / "fit.json"), "--data", str(run / "obs.csv"), "--report"]
    mine = _foreign(tmp_path)
    before = _snapshot(mine)
    with monkeypatch.context() as m:
        m.setattr(verify_module, "verify", lambda *a, **k: pytest.fail("verified before refusing the folder"))
        assert main([*argv, str(mine)]) == 2
    assert "not an earlier result" in capsys.readouterr().err
    assert _snapshot(mine) == before and not _leftovers(mine)

    rep = tmp_path / "rep"
    assert main([*argv, str(rep)]) == 0
    first = _snapshot(rep)
    assert set(first) == {"index.html", "before_after.png", "report.html", "report.pdf", "verify.json"}

    def interrupted(v, path):
        Path(path).write_bytes(b"half")
        raise KeyboardInterrupt

    with monkeypatch.context() as m:
        m.setattr(module, "plot_before_after", interrupted)
        assert main([*argv, str(rep)]) == 130
    assert _snapshot(rep) == first and not _leftovers(rep)
    assert main([*argv, str(rep)]) == 0
    assert set(_snapshot(rep)) == set(first)


# --- what counts as an earlier report ------------------------------------------------------------------

def _earlier_report(folder: Path, extra=()) -> Path:
    from kinid.files import write_text
    from kinid.reports.html import report_folder, report_page

    with report_folder(folder) as stage:
        (stage / "fig.png").write_bytes(b"\x89PNG")
        write_text(stage / "index.html", report_page("Earlier test report", "kinid test", [], [], []))
    for name in extra:
        (folder / name).write_text("x")
    return folder


def test_not_earlier_report(tmp_path):
    from kinid.reports.html import not_earlier_report

    assert not_earlier_report(_earlier_report(tmp_path / "a")) == []
    # a file the page does not list, a sub-folder, a listed name made a link: not the report's own
    assert not_earlier_report(_earlier_report(tmp_path / "b", extra=["data.csv"])) == ["data.csv"]
    c = _earlier_report(tmp_path / "c")
    (c / "sub").mkdir()
    assert not_earlier_report(c) == ["sub"]
    d = _earlier_report(tmp_path / "d")
    (d / "fig.png").unlink()
    (d / "fig.png").symlink_to(tmp_path / "b" / "data.csv")
    assert not_earlier_report(d) == ["fig.png"]
    # a page kinid did not write
    e = tmp_path / "e"
    e.mkdir()
    (e / "index.html").write_text("<html><head></head><body>my page</body></html>")
    assert not_earlier_report(e) == ["index.html"]
    # a page of kinid before the list: its figures and residuals.csv
    f = tmp_path / "f"
    f.mkdir()
    (f / "index.html").write_text('<html><head></head><body><table class="prov"><tbody><tr><td>report made by</td>'
                                  '<td>kinid 0.1.0</td></tr></tbody></table><img src="a.png"></body></html>')
    for name in ("a.png", "residuals.csv", "obs.csv"):
        (f / name).write_text("x")
    assert not_earlier_report(f) == ["obs.csv"]


def test_every_report_is_also_one_file_to_send(tmp_path):
    """report.html is index.html with every figure inside it: moved alone, it still shows them all."""
    import base64
    import re

    rep = tmp_path / "rep"
    assert main([*UVW, "--report", str(rep)]) == 0
    page, one = (rep / "index.html").read_text(), (rep / "report.html").read_text()
    figures = re.findall(r'<img src="([^"]+)"', page)
    inside = re.findall(r'<img src="data:image/png;base64,([^"]+)"', one)
    assert figures and len(inside) == len(figures)
    assert [base64.b64decode(d) for d in inside] == [(rep / f).read_bytes() for f in figures]
    assert not re.findall(r'(?:src|href)="(?!data:|https?:|#)[^"]*"', one)  # nothing outside the file
    assert re.findall(r"<h[12]>[^<]*</h[12]>", one) == re.findall(r"<h[12]>[^<]*</h[12]>", page)
