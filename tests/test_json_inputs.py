"""Every JSON file kinid reads goes through one validator (kinid.schema): tampered values are refused by name.

A fit, a sensor, a camera, a board, an error set and a compensation folder's compensation.json, each written by
kinid (or shipped as an example) and then changed as a careless or a hostile user would: a string where a number
goes, a negative standard deviation, 1e300, a range given backwards, a pixel of 1e-300 mm, a stand-off of
1e300 mm, distortion of 1e10. Each run is the command a user would type; it must end with exit status 2 and one
line naming the file and the key, and write nothing.
"""
from __future__ import annotations

import ast
import copy
import json
from pathlib import Path

import pytest

from kinid.cli import main
from kinid.urdf import path as urdf_path

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
MACHINE = str(urdf_path("five_axis_bc"))


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Valid inputs of every JSON kind, as kinid writes them."""
    from kinid.vision import CameraModel, make_board, save_board, save_camera

    d = tmp_path_factory.mktemp("json_inputs")
    assert main(["simulate", "--machine", MACHINE, "--errors", str(EXAMPLES / "errors.json"), "--noise-um", "1",
                 "--seed", "3", "--out", str(d / "obs.csv")]) == 0
    assert main(["identify", "--machine", MACHINE, "--data", str(d / "obs.csv"), "--add", "EXX:periodic:10",
                 "--out", str(d / "fit.json")]) == 0
    assert main(["compensate", "--fit", str(d / "fit.json"), "--out", str(d / "comp")]) == 0
    save_camera(CameraModel([[2000.0, 0, 640], [0, 2000.0, 480], [0, 0, 1]], [0.01, -0.02, 0, 0, 0], (1280, 960),
                            0.1), d / "camera.json")
    save_board(make_board(rows=4, cols=5, pitch_mm=16.0), d / "board.json")
    return d


def _load(path: Path):
    return json.loads(path.read_text(encoding="utf-8"))


def _set(data, where: str, value):
    """``data`` with the value at ``where`` (``a.b[2].c``) replaced."""
    data = copy.deepcopy(data)
    node = data
    keys = [int(k) if k.isdigit() else k for k in where.replace("[", ".").replace("]", "").split(".")]
    for k in keys[:-1]:
        node = node[k]
    node[keys[-1]] = value
    return data


def _first_axis(fit):
    return next(iter(fit["axis_ranges"]))


# kind, where, value, the text the message must hold (besides the file's name)
FIT_CASES = [
    ("parameters[0].value", "1.5", "parameters[0].value: must be a number"),
    ("parameters[0].value", 1e300, "parameters[0].value: must be a number in [-1e+07, 1e+07], got 1e+300"),
    ("parameters[0].std", -1.0, "parameters[0].std: must be a number in [0, 1e+07], got -1.0"),
    ("parameters[0].identified", "yes", "parameters[0].identified: must be true or false"),
    ("parameters[1].name", 7, "parameters[1].name: must be a string"),
    ("noise_um", 0, "noise_um: must be a number in (0, 1e+07], got 0"),
    ("rank", 2.5, "rank: must be an integer >= 0, got 2.5"),
    ("effects", "EXX", "effects: must be a list of strings"),
    ("machine.urdf", None, "machine.urdf: must not be null"),
]


@pytest.mark.parametrize("where, value, message", FIT_CASES)
def test_a_tampered_fit_is_refused_naming_the_key(files, tmp_path, capsys, where, value, message):
    bad = tmp_path / "fit.json"
    bad.write_text(json.dumps(_set(_load(files / "fit.json"), where, value)))
    _refused(["compensate", "--fit", str(bad), "--out", str(tmp_path / "out")], bad, message, capsys)
    assert not (tmp_path / "out").exists()


def test_a_fit_range_given_backwards_is_refused(files, tmp_path, capsys):
    fit = _load(files / "fit.json")
    axis = _first_axis(fit)
    bad = tmp_path / "fit.json"
    bad.write_text(json.dumps(_set(fit, f"axis_ranges.{axis}", fit["axis_ranges"][axis][::-1])))
    _refused(["compensate", "--fit", str(bad), "--out", str(tmp_path / "out")], bad,
             f"axis_ranges.{axis}: must be in increasing order", capsys)
    assert not (tmp_path / "out").exists()


SENSOR_CASES = [
    ({"pixel_mm": 1e-300}, "pixel_mm: must be a number in [1e-05, 10], got 1e-300"),
    ({"pixel_mm": "0.045"}, "pixel_mm: must be a number"),
    ({"image_x_angle_deg": 1e300}, "image_x_angle_deg: must be a number in [-360, 360], got 1e+300"),
    ({"laser_standoff_mm": 1e300}, "laser_standoff_mm: must be a number in [-1000, 1000], got 1e+300"),
    ({"laser_offset_std_mm": [0.01, -0.01]}, "laser_offset_std_mm[1]: must be a number in [0, 200], got -0.01"),
    ({"pixel_mm": None, "camera": {"camera_matrix": [[2000, 0, 640], [0, 2000, 480], [0, 0, 1]],
                                   "dist_coeffs": [1e10, 0, 0, 0, 0], "image_size": [1280, 960]},
      "working_distance_mm": 100}, "dist_coeffs[0]: must be a number in [-1000, 1000], got 10000000000.0"),
]


@pytest.mark.parametrize("change, message", SENSOR_CASES)
def test_a_tampered_sensor_is_refused_naming_the_key(tmp_path, capsys, change, message):
    run = EXAMPLES / "run"
    bad = tmp_path / "sensor.json"
    bad.write_text(json.dumps({**_load(run / "sensor.json"), **change}))
    _refused(["observe", "--machine", MACHINE, "--board", str(run / "board.json"), "--sensor", str(bad),
              "--data", str(run / "log.csv"), "--out", str(tmp_path / "o.csv")], bad, message, capsys)
    assert not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize("where, value, message", [
    ("camera_matrix[0][0]", "2000", "camera_matrix[0][0]: must be a number"),
    ("dist_coeffs[1]", 1e10, "dist_coeffs[1]: must be a number in [-1000, 1000]"),
    ("image_size[0]", 0, "image_size[0]: must be an integer in [1, 100000], got 0"),
    ("rms_px", -0.1, "rms_px: must be a number in [0, 1000], got -0.1"),
])
def test_a_tampered_camera_is_refused_naming_the_key(files, tmp_path, capsys, where, value, message):
    run = EXAMPLES / "run"
    bad = tmp_path / "camera.json"
    bad.write_text(json.dumps(_set(_load(files / "camera.json"), where, value)))
    sensor = tmp_path / "sensor.json"
    sensor.write_text(json.dumps({"camera": "camera.json", "working_distance_mm": 100}))
    _refused(["observe", "--machine", MACHINE, "--board", str(run / "board.json"), "--sensor", str(sensor),
              "--data", str(run / "log.csv"), "--out", str(tmp_path / "o.csv")], bad, message, capsys)


@pytest.mark.parametrize("where, value, message", [
    ("pitch_mm", 1e300, "pitch_mm: must be a number in (0, 10000], got 1e+300"),
    ("rows", -4, "rows: must be an integer in [1, 10000], got -4"),
    ("ring_outer_d_mm", "9", "ring_outer_d_mm: must be a number"),
    ("codes[0][0]", -1, "codes[0][0]: must be an integer in [0, "),
])
def test_a_tampered_board_is_refused_naming_the_key(files, tmp_path, capsys, where, value, message):
    bad = tmp_path / "board.json"
    bad.write_text(json.dumps(_set(_load(files / "board.json"), where, value)))
    _refused(["plan", "--machine", MACHINE, "--board", str(bad), "--count", "20", "--out", str(tmp_path / "p.csv")],
             bad, message, capsys)
    assert not (tmp_path / "p.csv").exists()


@pytest.mark.parametrize("value, message", [
    ("8", "EX0C: must be a number in [-1e+07, 1e+07] or a list of at least 1 numbers, got '8'"),
    (1e300, "EX0C: must be a number in [-1e+07, 1e+07]"),
    ([], "EX0C: must be a list of at least 1 numbers, got 0 item(s)"),
])
def test_a_tampered_error_set_is_refused_naming_the_effect(tmp_path, capsys, value, message):
    bad = tmp_path / "errors.json"
    bad.write_text(json.dumps({**_load(EXAMPLES / "errors.json"), "EX0C": value}))
    _refused(["simulate", "--machine", MACHINE, "--errors", str(bad), "--out", str(tmp_path / "o.csv")], bad,
             message, capsys)
    assert not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize("where, value, message", [
    ("fit.file", 3, "fit.file: must be a string, got 3"),
    ("fit.sha256", None, "fit.sha256: must not be null"),
])
def test_a_tampered_compensation_file_is_refused_naming_the_key(files, tmp_path, capsys, where, value, message):
    folder = tmp_path / "comp"
    folder.mkdir()
    (folder / "compensation.json").write_text(json.dumps(_set(_load(files / "comp" / "compensation.json"), where,
                                                              value)))
    _refused(["verify", "--compensation", str(folder), "--data", str(files / "obs.csv")],
             folder / "compensation.json", message, capsys)


def test_every_json_read_is_validated():
    """Every function of the package that reads a JSON file checks it against a schema (kinid.schema.validate),
    except those that only recognise kinid's own earlier outputs (and treat anything else as foreign)."""
    recognisers = {"not_earlier_report", "_not_earlier_compensation"}
    readers, unchecked = [], []
    for folder in ("kinid", "identification", "vision", "stages", "urdf"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if not isinstance(node, ast.FunctionDef) or node.name == "read_json":
                    continue
                calls = {c.func.id if isinstance(c.func, ast.Name) else getattr(c.func, "attr", "")
                         for c in ast.walk(node) if isinstance(c, ast.Call)}
                if calls & {"read_json", "loads"}:
                    readers.append(node.name)
                    if not calls & {"validate", "camera_from_dict"} and node.name not in recognisers:
                        unchecked.append(f"{path.relative_to(ROOT)}:{node.name}")
    assert len(readers) >= 8, readers
    assert unchecked == [], f"JSON read without a schema: {unchecked}"


def _refused(argv, path: Path, message: str, capsys):
    capsys.readouterr()
    status = main(argv)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert status == 2, err
    assert len(lines) == 1 and "Traceback" not in err, err
    assert path.name in lines[0] and message in lines[0], (message, lines[0])
