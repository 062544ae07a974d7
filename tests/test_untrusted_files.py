"""Files named by untrusted input (the command line, a run log) and what kinid prints or allocates from options.

- every reader of kinid.files (read_limited_text, read_csv_rows, read_json, read_image) refuses, quickly and with
  one error naming the file, a FIFO (whose open would wait for ever), a device (``/dev/zero`` through a link: no
  end), a folder, a socket, and names with a NUL byte or a control character (shown escaped, never raw);
- ``kinid observe`` with a run log naming a FIFO: exit 2, one line;
- ``--json`` outputs are strict JSON (no NaN, no Infinity);
- a grid step or a board pitch that would make a huge table or page is refused before anything is allocated
  or written.

Each call that could hang runs in a forked child with a 10 s limit, so a regression fails instead of hanging.
"""
from __future__ import annotations

import io
import json
import math
import multiprocessing
import os
import socket
import stat
import sys
import traceback
from contextlib import redirect_stderr, redirect_stdout

import numpy as np
import pytest

from kinid.cli import main
from kinid.errors import DataError, ImageError, KinidError
from kinid.files import (MAX_IMAGE_BYTES, read_csv_rows, read_image, read_json, read_limited_text,
                         read_untrusted_bytes, shown_path, strict_json)

LIMIT_S = 10.0

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="FIFOs, /dev/zero and fork: Linux")


def _in_child(conn, fn, args):
    try:
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))  # a regression reading /dev/zero fails, not the box
    except (ImportError, ValueError, OSError):
        pass
    try:
        out = fn(*args)
        try:
            conn.send(("ok", out))
        except Exception:  # noqa: BLE001  (not picklable: its repr will do)
            conn.send(("ok", repr(out)[:200]))
    except KinidError as exc:
        conn.send(("error", type(exc).__name__, str(exc)))
    except BaseException as exc:  # noqa: BLE001  (a traceback is a failure the parent reports)
        conn.send(("crash", type(exc).__name__, "".join(traceback.format_exception(exc))[-2000:]))
    finally:
        conn.close()


def guarded(fn, *args, limit=LIMIT_S):
    """``fn(*args)`` in a forked child (everything already imported): its outcome, or a failure after ``limit`` s."""
    ctx = multiprocessing.get_context("fork")
    parent, child = ctx.Pipe(duplex=False)
    p = ctx.Process(target=_in_child, args=(child, fn, args), daemon=True)
    p.start()
    child.close()
    try:
        if not parent.poll(limit):
            pytest.fail(f"{getattr(fn, '__name__', fn)}{args!r} did not return within {limit:g} s (a hang)")
        return parent.recv()
    finally:
        if p.is_alive():
            p.kill()
        p.join(5)
        parent.close()


def _text(p):
    return read_limited_text(p, what="machine file", max_bytes=1 << 20)


def _csv(p):
    return read_csv_rows(p, what="run log")


READERS = {"read_limited_text": (_text, DataError), "read_csv_rows": (_csv, DataError),
           "read_json": (read_json, DataError), "read_image": (read_image, ImageError)}


def _fifo(tmp_path):
    p = tmp_path / "pipe.csv"
    os.mkfifo(p)
    return p, "FIFO"


def _dev_zero(tmp_path):
    p = tmp_path / "zero.png"
    p.symlink_to("/dev/zero")
    return p, "character device"


def _folder(tmp_path):
    p = tmp_path / "folder.json"
    p.mkdir()
    return p, "is a folder"


def _nul(tmp_path):
    return str(tmp_path / "a\x00b.png"), "NUL byte"


def _escape(tmp_path):
    p = tmp_path / "\x1b[31mred.png"
    p.write_bytes(b"{}")  # exists, and is refused for its name alone
    return p, "control character"


CASES = {"fifo": _fifo, "dev_zero_link": _dev_zero, "folder": _folder, "nul": _nul, "escape": _escape}


@pytest.mark.parametrize("reader", list(READERS))
@pytest.mark.parametrize("case", list(CASES))
def test_readers_refuse_what_is_no_regular_file(tmp_path, reader, case):
    fn, error = READERS[reader]
    path, words = CASES[case](tmp_path)
    outcome = guarded(fn, path)
    assert outcome[0] == "error", outcome
    kind, message = outcome[1], outcome[2]
    assert kind == error.__name__, outcome
    assert words in message, message
    assert len(message.splitlines()) == 1, message
    assert "\x1b" not in message and "\x00" not in message, repr(message)  # escaped, never raw
    name = os.path.basename(os.fsdecode(path))
    assert (name if name.isprintable() else repr(str(path))) in message, message


@pytest.mark.parametrize("reader", list(READERS))
def test_readers_refuse_a_socket(tmp_path, reader):
    fn, error = READERS[reader]
    path = tmp_path / "s.sock"
    if len(os.fsencode(path)) >= 100:
        pytest.skip("temporary folder too deep for a Unix socket name")
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.bind(str(path))
        assert stat.S_ISSOCK(os.stat(path).st_mode)
        outcome = guarded(fn, path)
    assert outcome[0] == "error" and outcome[1] == error.__name__ and "socket" in outcome[2], outcome


def test_links_to_regular_files_are_read(tmp_path):
    (tmp_path / "real.json").write_text('{"a": 1}')
    (tmp_path / "link.json").symlink_to(tmp_path / "real.json")
    assert read_json(tmp_path / "link.json") == {"a": 1}
    (tmp_path / "r.csv").write_text("a,b\n1,2\n")
    assert read_csv_rows(tmp_path / "r.csv") == [(1, ["a", "b"]), (2, ["1", "2"])]
    # a printable non-ASCII name is fine and shown as it is
    (tmp_path / "mesuré µm.json").write_text("[1]")
    assert read_json(tmp_path / "mesuré µm.json") == [1]
    assert shown_path("mesuré µm.json") == "mesuré µm.json"
    assert shown_path("a\x1b[2Jb") == repr("a\x1b[2Jb")


def test_size_is_checked_from_stat_before_reading(tmp_path):
    big = tmp_path / "big.png"
    with open(big, "wb") as f:  # sparse: large by stat, nothing to read
        f.truncate(MAX_IMAGE_BYTES + 1)
    outcome = guarded(read_image, big)
    assert outcome[0] == "error" and "larger than" in outcome[2], outcome
    small = tmp_path / "t.txt"
    small.write_bytes(b"x" * 11)
    with pytest.raises(DataError, match=r"t\.txt: machine file is larger than 10 bytes"):
        read_limited_text(small, what="machine file", max_bytes=10)
    assert read_untrusted_bytes(small, what="file", max_bytes=11) == b"x" * 11


def test_missing_files_keep_their_messages(tmp_path):
    with pytest.raises(DataError, match="machine file not found"):
        _text(tmp_path / "none.urdf")
    with pytest.raises(ImageError, match="image file does not exist"):
        read_image(tmp_path / "none.png")


# --- through the command line: kinid observe with a run log naming a FIFO -------------------------------------

def _cli(argv):
    err, out = io.StringIO(), io.StringIO()
    with redirect_stderr(err), redirect_stdout(out):
        status = main(argv)
    return status, err.getvalue(), out.getvalue()


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    import bc_camera_sim as sim

    folder = tmp_path_factory.mktemp("run")
    sim.write_run(folder, sim.plan()[:3], rng=np.random.default_rng(5))
    return folder


@pytest.mark.parametrize("name, words", [("images/pipe.png", "FIFO (named pipe)"),
                                         ("/dev/zero", "character device"),
                                         ("images/\x1b[31mred.png", "control character"),
                                         ("images", "is a folder")])
def test_observe_with_a_log_naming_a_fifo_or_device(short_run, tmp_path, name, words):
    from kinid.urdf import path as urdf_path

    folder = short_run
    (tmp_path / "images").mkdir()
    os.mkfifo(tmp_path / "images" / "pipe.png")
    (tmp_path / "images" / "\x1b[31mred.png").write_bytes((folder / "images" / "000.png").read_bytes())
    for f in ("board.json", "sensor.json"):
        (tmp_path / f).write_text((folder / f).read_text())
    lines = (folder / "log.csv").read_text().splitlines()
    first = lines[1].split(",")
    lines[1] = ",".join([name, *first[1:]])
    (tmp_path / "log.csv").write_text("\n".join(lines) + "\n")
    argv = ["observe", "--machine", str(urdf_path("five_axis_bc")), "--board", str(tmp_path / "board.json"),
            "--sensor", str(tmp_path / "sensor.json"), "--data", str(tmp_path / "log.csv"),
            "--out", str(tmp_path / "obs.csv")]
    outcome = guarded(_cli, argv, limit=60.0)  # the verb loads the machine first; a FIFO would hang for ever
    assert outcome[0] == "ok", outcome
    status, err, _ = outcome[1]
    assert status == 2, err
    assert len(err.strip().splitlines()) == 1 and words in err, err
    assert "\x1b" not in err, repr(err)
    assert not (tmp_path / "obs.csv").exists()


# --- --json outputs are strict JSON --------------------------------------------------------------------------

def _strict(text):
    def refuse(name):
        raise ValueError(f"{name} is not JSON")
    return json.loads(text, parse_constant=refuse)


def test_strict_json_turns_non_finite_numbers_into_null():
    data = {"a": math.inf, "b": [1.0, math.nan, -math.inf], "c": np.float32("nan"), "d": np.array([1.0, np.inf]),
            "e": (np.float64(2.5), np.int64(3)), "f": "NaN"}
    assert _strict(strict_json(data)) == {"a": None, "b": [1.0, None, None], "c": None, "d": [1.0, None],
                                          "e": [2.5, 3], "f": "NaN"}


def test_iso230_2_json_is_strict(tmp_path, capsys):
    runs = tmp_path / "runs.csv"
    rows = ["target_mm,run,direction,deviation_um", "0,1,1,1e308", "0,2,1,-1e308", "0,1,-1,1e308", "0,2,-1,1e308",
            "10,1,1,1", "10,2,1,2", "10,1,-1,1", "10,2,-1,3"]
    runs.write_text("\n".join(rows) + "\n")
    # deviations of 1e308 µm squared to infinity and gave null results with exit 0; a deviation beyond a metre is
    # now refused at the door, naming its line and column, and nothing is printed as a result
    assert main(["iso230-2", "--data", str(runs), "--json"]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1 and "deviation_um" in captured.err
    runs.write_text("\n".join(rows[:1] + ["0,1,1,1", "0,2,1,-1", "0,1,-1,1", "0,2,-1,1"] + rows[5:]) + "\n")
    assert main(["iso230-2", "--data", str(runs), "--json"]) == 0
    out = _strict(capsys.readouterr().out)
    assert out["positions"][1]["mean_um"] == pytest.approx(1.75)


def test_dual_axis_json_is_strict(tmp_path, capsys):
    data = tmp_path / "meas.csv"
    data.write_text("camera_y_mm,shift_x_px,shift_y_px\n" + "".join(f"{10 * i},{i * i},{i}\n" for i in range(9)))
    assert main(["dual-axis", "--data", str(data), "--pixel-to-mm", "1e307", "0", "0", "1e307", "--json"]) == 0
    rep = _strict(capsys.readouterr().out)
    assert rep["smooth"]["parallelism_urad"] is None


# --- sizes bounded before allocation ---------------------------------------------------------------------------

@pytest.fixture(scope="module")
def fit_file(tmp_path_factory):
    from kinid.identification import default_model, fit, load_machine, parse_effect, save_fit
    from kinid.identification.fitting.simulate import patent_plan, simulate
    from kinid.urdf import path as urdf_path

    folder = tmp_path_factory.mktemp("fit")
    m = load_machine(urdf_path("five_axis_bc"))
    truth = {"EXX:poly2": [0.2, -0.01], "ECC:periodic:90": [4.0, 2.0]}  # tens of µm: a size a machine has
    effects = [parse_effect(n, m) for n in truth]
    theta = np.concatenate([np.atleast_1d(v) for v in truth.values()]).astype(float)
    obs = simulate(m, patent_plan(m), effects, theta, noise_um=0.5, rng=np.random.default_rng(3))
    result = fit(m, obs, list(default_model(m)) + effects, noise_um=0.5)
    save_fit(result, folder / "fit.json")
    return folder / "fit.json"


@pytest.mark.parametrize("option, value, message", [
    ("--step-mm", "1e-9", "[0.001, 10000] (step in mm)"), ("--step-mm", "1e-6", "[0.001, 10000] (step in mm)"),
    ("--step-deg", "1e-7", "[0.0001, 360] (step in °)"), ("--step-mm", "0.0011", "1,000,000 points")])
def test_compensate_refuses_a_step_too_fine(fit_file, tmp_path, option, value, message):
    """A step below the plausible bound of a table's step is refused at the door (it was also refused where a
    table would use it, but accepted by a fit without tables); one within it that would still make more than a
    million points is refused before anything is allocated."""
    out = tmp_path / "comp"
    outcome = guarded(_cli, ["compensate", "--fit", str(fit_file), "--out", str(out), option, value,
                             "--table-range", "travel"], limit=60.0)
    assert outcome[0] == "ok", outcome
    status, err, _ = outcome[1]
    assert status == 2 and len(err.strip().splitlines()) == 1, err
    assert message in err and (value.replace("1e-", "1e-0") in err or value in err), err
    if option == "--step-deg":
        assert "--step-deg" in err, err
    assert not out.exists()


def test_table_grid_checks_the_step_before_allocating():
    from kinid.identification.compensation.table_grids import AxisRange, check_grid_step, table_grid

    rng = AxisRange(-500.0, 500.0, "URDF travel", False, (-500.0, 500.0), None)
    with pytest.raises(DataError, match=r"step_mm 1e-09 would put 1e\+12 points .* limit of 1,000,000"):
        check_grid_step(1e-9, -500.0, 500.0, parameter="step_mm")
    with pytest.raises(DataError, match="1,000,000"):
        table_grid(None, rng, None, 20001, 1e-6)
    with pytest.raises(DataError, match="must be a positive number"):
        table_grid(None, rng, None, 20001, math.nan, parameter="step_mm")
    assert table_grid(None, rng, None, 20001, 0.5).size == 2001


def test_board_refuses_a_page_larger_than_two_metres(tmp_path, capsys):
    argv = ["board", "--out", str(tmp_path / "b.json"), "--svg", str(tmp_path / "b.svg"), "--pdf",
            str(tmp_path / "b.pdf"), "--pitch-mm", "1e300"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "--pitch-mm" in err and "2000 mm" in err, err
    assert list(tmp_path.iterdir()) == []
    assert main(["board", "--out", str(tmp_path / "b.json"), "--rows", "40", "--cols", "40", "--pitch-mm", "60",
                 "--bits", "16"]) == 2
    assert "larger than kinid draws" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
