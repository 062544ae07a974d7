"""Folder outputs are written whole or not at all (kinid.folders.staged_folder), shown on ``kinid compensate``.

Every run is a real ``kinid compensate`` process. A small driver (written next to the data) runs the command
line and, on request, slows the writing down, kills the process with SIGKILL or SIGINT at a chosen point, or
makes the n-th write fail with an OSError (ENOSPC, EACCES). After each, the output folder must be, byte for
byte, the complete earlier result or the complete new one.
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from kinid.urdf import path as urdf_path

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"

DRIVER = r'''
"""kinid's command line with faults put in: KT_MODE, KT_ARG, KT_SLEEP (s before each file in the staged folder)."""
import errno
import os
import signal
import sys
import time

# Ctrl-C as at a terminal, even where the suite was started with SIGINT ignored (a shell's background job:
# Python then installs no KeyboardInterrupt handler, and the SIGINT cases would exit 0)
signal.signal(signal.SIGINT, signal.default_int_handler)

import kinid.files as kf
import kinid.folders as kd

MODE = os.environ.get("KT_MODE", "")
ARG = os.environ.get("KT_ARG", "")
SLEEP = float(os.environ.get("KT_SLEEP", "0") or 0)
STAGED = ".kinid-new-"


def staged_fd(fd):
    try:
        return STAGED in os.readlink(f"/proc/self/fd/{fd}")
    except OSError:
        return False


def die(sig=signal.SIGKILL):
    os.kill(os.getpid(), sig)
    time.sleep(5)  # SIGINT: the KeyboardInterrupt comes at the next bytecode


files = [0]
real_write_text = kf.write_text


def write_text(path, text):
    if STAGED in str(path):
        files[0] += 1
        if SLEEP:
            time.sleep(SLEEP)
        if MODE == "kill-before-file" and files[0] == int(ARG):
            die()
        if MODE == "kill-mid-file" and files[0] == int(ARG):
            with kf.atomic_write(path) as f:
                f.write(text[: len(text) // 2])
                f.flush()
                die()
    return real_write_text(path, text)


kf.write_text = write_text

opened = [0]
real_fdopen = os.fdopen


class Failing:
    """A file whose writes fail like a full disk (or a refused write)."""

    def __init__(self, f, code):
        self._f, self._code = f, code

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._f.close()
        return False

    def write(self, text):
        raise OSError(self._code, os.strerror(self._code))

    def __getattr__(self, name):
        return getattr(self._f, name)


def fdopen(fd, *args, **kwargs):
    f = real_fdopen(fd, *args, **kwargs)
    if MODE.startswith("fail-write-") and staged_fd(fd):
        opened[0] += 1
        if opened[0] == int(ARG):
            return Failing(f, getattr(errno, MODE.rsplit("-", 1)[1]))
    return f


os.fdopen = fdopen

synced = [0]
real_fsync = os.fsync


def fsync(fd):
    if MODE == "fail-fsync-ENOSPC" and staged_fd(fd):
        synced[0] += 1
        if synced[0] == int(ARG):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    return real_fsync(fd)


os.fsync = fsync

real_mkdir = os.mkdir


def mkdir(path, *args, **kwargs):
    if MODE.startswith("fail-mkdir-") and STAGED in os.fsdecode(path):
        code = getattr(errno, MODE.rsplit("-", 1)[1])
        raise OSError(code, os.strerror(code), os.fsdecode(path))
    return real_mkdir(path, *args, **kwargs)


os.mkdir = mkdir

real_swap, real_remove = kd._swap, kd._remove_tree
swapped = [False]


def swap(staged, target):
    if MODE == "kill-before-swap":
        die()
    if MODE == "sigint-before-swap":
        die(signal.SIGINT)
    earlier = real_swap(staged, target)
    swapped[0] = True
    if MODE == "kill-after-swap":
        die()
    if MODE == "sigint-after-swap":
        die(signal.SIGINT)
    return earlier


def remove(path):
    if MODE == "kill-removing-earlier" and swapped[0]:
        for name in sorted(os.listdir(path))[:3]:
            os.unlink(os.path.join(path, name))
        die()
    return real_remove(path)


kd._swap, kd._remove_tree = swap, remove

if MODE.startswith("fallback"):  # a file system that cannot swap two folders in one step
    kd._exchange = lambda a, b: False
    real_rename = os.rename

    def rename(src, dst):
        real_rename(src, dst)
        if MODE == "fallback-kill-between-renames" and ".kinid-old-" in os.fsdecode(dst):
            die()

    os.rename = rename

from kinid.cli import main  # noqa: E402

sys.exit(main(sys.argv[1:]))
'''


def _kinid(*args, cwd):
    subprocess.run([sys.executable, "-m", "kinid", *map(str, args)], cwd=cwd, check=True, capture_output=True)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """Two fits of the five-axis machine (A: X tables; B: X and Y tables) and their compensation folders."""
    d = tmp_path_factory.mktemp("folders")
    (d / "driver.py").write_text(DRIVER)
    machine = urdf_path("five_axis_bc")
    (d / "eb.json").write_text(json.dumps({"EX0C": -8.0, "EA0B": 20.0, "EXX:periodic:10": [0.9, 1.1],
                                           "EYY:poly2": [0.04, -2e-4]}))  # µm over the travel: significant as a curve
    for name, errors, seed, added in (("a", EXAMPLES / "errors.json", 1, ["EXX:periodic:10"]),
                                      ("b", d / "eb.json", 2, ["EXX:periodic:10", "EYY:poly2"])):
        _kinid("simulate", "--machine", machine, "--errors", errors, "--noise-um", 1, "--seed", seed,
               "--out", d / f"{name}.csv", cwd=d)
        _kinid("identify", "--machine", machine, "--data", d / f"{name}.csv", "--add", *added,
               "--out", d / f"{name}.json", cwd=d)
    refs = {}
    for name in "ab":
        _kinid("compensate", "--fit", d / f"{name}.json", "--out", d / f"ref_{name}", cwd=d)
        refs[name] = snapshot(d / f"ref_{name}")
    assert refs["a"] != refs["b"] and set(refs["b"]) > set(refs["a"])  # B has Y tables A has not
    return d, refs


def snapshot(folder: Path) -> dict:
    """name -> bytes of every file in ``folder`` (which must hold regular files only)."""
    out = {}
    for p in sorted(folder.iterdir()):
        assert p.is_file() and not p.is_symlink(), p
        out[p.name] = p.read_bytes()
    return out


def start(d: Path, fit: str, out: Path, mode: str = "", arg="", sleep: float = 0.0, extra=(), prefix=()):
    env = {**os.environ, "KT_MODE": mode, "KT_ARG": str(arg), "KT_SLEEP": str(sleep)}
    cmd = [*prefix, sys.executable, str(d / "driver.py"), "compensate", "--fit", str(d / f"{fit}.json"),
           "--out", str(out), *extra]
    return subprocess.Popen(cmd, cwd=d, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def run(d, fit, out, mode="", arg="", sleep=0.0, extra=(), prefix=()):
    p = start(d, fit, out, mode, arg, sleep, extra, prefix)
    stdout, stderr = p.communicate(timeout=120)
    return p.returncode, stdout, stderr


def which(out: Path, refs: dict) -> str:
    """'a' or 'b': the complete result ``out`` holds (fails on anything else)."""
    assert out.is_dir(), f"{out} is missing"
    got = snapshot(out)
    for name, ref in refs.items():
        if got == ref:
            return name
    pytest.fail(f"{out} holds neither complete result: {sorted(got)}")


def leftovers(out: Path) -> list:
    return sorted(p.name for p in out.parent.iterdir() if p.name != out.name)


def fresh(d: Path, refs: dict, fit: str = "a", name: str = "out") -> Path:
    """A folder of its own holding the complete result of ``fit`` (a copy of the one ``kinid compensate`` wrote)."""
    parent = d / f"w_{name}_{time.monotonic_ns()}"
    parent.mkdir()
    out = parent / name
    shutil.copytree(d / f"ref_{fit}", out)
    assert which(out, refs) == fit and leftovers(out) == []
    return out


def one_line_error(err: str, status: int) -> str:
    assert status == 2, err
    assert "Traceback" not in err, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("kinid compensate: "), err
    return lines[0]


# --- (a) SIGKILL at any moment: the earlier result or the new one, whole ---------------------------------------

def test_sigkill_at_any_moment_leaves_the_earlier_or_the_new_result(data):
    d, refs = data
    out = fresh(d, refs, "a")
    # how long a slowed run takes, start of the process to its end
    t0 = time.monotonic()
    status, _, err = run(d, "b", out, sleep=0.04)
    total = time.monotonic() - t0
    assert status == 0, err
    assert which(out, refs) == "b" and leftovers(out) == []
    seen = {"old": 0, "new": 0}
    points = [("timed", k * total / 11) for k in range(12)]  # 12 instants from 0 to the end of a run
    points += [("kill-before-file", n) for n in (1, 5, 8)] + [("kill-mid-file", n) for n in (1, 4, 8)]  # A: 8 files
    points += [("kill-before-swap", ""), ("kill-after-swap", ""), ("kill-removing-earlier", "")]
    for mode, arg in points:
        before = which(out, refs)
        fit = "b" if before == "a" else "a"
        if mode == "timed":
            p = start(d, fit, out, sleep=0.04)
            time.sleep(arg)
            p.send_signal(signal.SIGKILL)
            p.communicate(timeout=60)
        else:
            status, _, err = run(d, fit, out, mode, arg)
            assert status == -signal.SIGKILL, (mode, arg, status, err)
        now = which(out, refs)  # whole: one result or the other, nothing mixed
        seen["old" if now == before else "new"] += 1
        assert all(n == out.name or n.startswith(f".{out.name}.kinid-") for n in leftovers(out)), leftovers(out)
        if mode in ("kill-before-file", "kill-mid-file", "kill-before-swap"):
            assert now == before, mode
        if mode in ("kill-after-swap", "kill-removing-earlier"):
            assert now == fit, mode
    print(f"{len(points)} kills over a run of {total:.2f} s: earlier result kept {seen['old']}, "
          f"new result in place {seen['new']}")
    assert seen["old"] >= 3 and seen["new"] >= 2
    # the next run clears what the killed ones left and writes its result
    before = which(out, refs)
    fit = "b" if before == "a" else "a"
    status, _, err = run(d, fit, out)
    assert status == 0, err
    assert which(out, refs) == fit and leftovers(out) == []


def test_a_run_killed_between_the_two_renames_is_put_back_by_the_next(data):
    """Where the file system cannot swap two folders in one step the earlier one is renamed aside first; a kill
    between the renames leaves it aside, and the next run puts it back before anything else."""
    d, refs = data
    out = fresh(d, refs, "a")
    status, _, _ = run(d, "b", out, "fallback-kill-between-renames")
    assert status == -signal.SIGKILL
    assert not out.exists() and any(".kinid-old-" in n for n in leftovers(out))
    # the next run fails (a full disk) after putting the earlier result back: the folder is A again
    status, _, err = run(d, "b", out, "fail-write-ENOSPC", 1)
    one_line_error(err, status)
    assert which(out, refs) == "a" and leftovers(out) == []
    status, _, err = run(d, "b", out, "fallback")  # the two-rename way to its end
    assert status == 0, err
    assert which(out, refs) == "b" and leftovers(out) == []


# --- (b) Ctrl-C ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("delay", [0.0, 0.1, 0.3])
def test_sigint_while_writing_exits_130_and_keeps_the_earlier_result(data, delay):
    d, refs = data
    out = fresh(d, refs, "a")
    p = start(d, "b", out, sleep=0.1)  # 12 files, 0.1 s each
    deadline = time.monotonic() + 60
    while not any(".kinid-new-" in n for n in leftovers(out)):  # the staged folder is being written
        assert p.poll() is None and time.monotonic() < deadline
        time.sleep(0.005)
    time.sleep(delay)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130, err
    assert err.strip().splitlines() == ["kinid compensate: interrupted"], err
    assert which(out, refs) == "a" and leftovers(out) == []


@pytest.mark.parametrize("mode, result", [("sigint-before-swap", "a"), ("sigint-after-swap", "b")])
def test_sigint_at_the_swap(data, mode, result):
    d, refs = data
    out = fresh(d, refs, "a")
    status, _, err = run(d, "b", out, mode)
    assert status == 130, err
    assert which(out, refs) == result and leftovers(out) == []


# --- (c, d) full disk, refused writes, read-only folders -------------------------------------------------------

@pytest.mark.parametrize("mode, arg", [("fail-write-ENOSPC", n) for n in (1, 2, 6, 12)]
                         + [("fail-fsync-ENOSPC", n) for n in (1, 12)]
                         + [("fail-write-EACCES", 3), ("fail-write-EROFS", 7), ("fail-mkdir-ENOSPC", ""),
                            ("fail-mkdir-EACCES", "")])
def test_a_failed_write_is_one_line_naming_the_file_and_the_earlier_result_stays(data, mode, arg):
    d, refs = data
    out = fresh(d, refs, "a")
    status, _, err = run(d, "b", out, mode, arg)
    line = one_line_error(err, status)
    code = mode.rsplit("-", 1)[1]
    assert os.strerror(getattr(__import__("errno"), code)) in line, line
    assert str(out) in line and ".kinid-new-" not in line, line
    if mode.startswith(("fail-write", "fail-fsync")):  # the file that failed, in the folder asked for
        assert any(f"{out}{os.sep}{name}:" in line for name in refs["b"]), line
    assert which(out, refs) == "a" and leftovers(out) == []


def _unprivileged() -> list:
    """A command prefix under which file permissions hold: none for a user, and for root (who writes into
    read-only folders) setpriv without the capabilities that override them, where the system allows it."""
    if os.geteuid() != 0:
        return []
    drop = "-dac_override,-dac_read_search,-fowner"
    prefix = [shutil.which("setpriv") or "setpriv", f"--inh-caps={drop}", f"--bounding-set={drop}"]
    try:
        if subprocess.run([*prefix, "true"], capture_output=True).returncode == 0:
            return prefix
    except OSError:
        pass
    pytest.skip("running as root, which ignores permissions, and setpriv cannot drop that; the mocked EACCES "
                "cases stand in for this one")


def test_read_only_folder_is_refused_and_kept(data):
    d, refs = data
    prefix = _unprivileged()
    out = fresh(d, refs, "a")
    os.chmod(out, 0o555)
    try:
        status, _, err = run(d, "b", out, prefix=prefix)
        line = one_line_error(err, status)
        assert str(out) in line and "read-only" in line, line
        assert which(out, refs) == "a" and leftovers(out) == []
        os.chmod(out, 0o755)
        os.chmod(out.parent, 0o555)  # no room for the new folder (or the lock) beside it
        status, _, err = run(d, "b", out, prefix=prefix)
        line = one_line_error(err, status)
        assert str(out) in line and "Permission denied" in line, line
    finally:
        os.chmod(out.parent, 0o755)
        os.chmod(out, 0o755)
    assert which(out, refs) == "a" and leftovers(out) == []


# --- (b) two writers at once --------------------------------------------------------------------------------

def test_a_second_writer_is_refused_while_the_first_writes(data):
    d, refs = data
    out = fresh(d, refs, "a")
    first = start(d, "b", out, sleep=1.0)  # 12 files, 1 s each: the second writer starts, reads and computes before the first ends
    deadline = time.monotonic() + 60
    while not any(".kinid-new-" in n for n in leftovers(out)):
        assert first.poll() is None and time.monotonic() < deadline
        time.sleep(0.005)
    status, _, err = run(d, "a", out)
    line = one_line_error(err, status)
    assert "another kinid is writing" in line and str(out) in line
    _, err = first.communicate(timeout=60)
    assert first.returncode == 0, err
    assert which(out, refs) == "b" and leftovers(out) == []


# --- (e, f) inputs in the folder, folders that are not kinid's ---------------------------------------------------

@pytest.mark.parametrize("name", ["compensation.json", "X.comp", "fit.json"])
def test_the_fit_inside_the_folder_is_refused_before_anything_is_written(data, name):
    d, refs = data
    out = fresh(d, refs, "a")
    shutil.copy(d / "b.json", out / name)
    before = snapshot(out)
    p = subprocess.run([sys.executable, "-m", "kinid", "compensate", "--fit", str(out / name), "--out", str(out)],
                       cwd=d, capture_output=True, text=True)
    line = one_line_error(p.stderr, p.returncode)
    assert name in line and "--fit" in line and "input" in line, line
    assert snapshot(out) == before and leftovers(out) == []


def test_the_machine_urdf_named_by_the_fit_inside_the_folder_is_refused(data, tmp_path):
    """A fit identified on ``OUT/calibrated.urdf`` (the machine of an earlier compensation) may not replace it."""
    d, refs = data
    out = tmp_path / "w" / "out"
    out.mkdir(parents=True)
    shutil.copy(urdf_path("five_axis_bc"), out / "calibrated.urdf")
    _kinid("identify", "--machine", out / "calibrated.urdf", "--data", d / "a.csv", "--out", tmp_path / "fit.json",
           cwd=tmp_path)
    before = snapshot(out)
    p = subprocess.run([sys.executable, "-m", "kinid", "compensate", "--fit", str(tmp_path / "fit.json"),
                        "--out", str(out)], cwd=tmp_path, capture_output=True, text=True)
    line = one_line_error(p.stderr, p.returncode)
    assert "calibrated.urdf" in line and "input" in line, line
    assert snapshot(out) == before and leftovers(out) == []


@pytest.mark.parametrize("earlier", [False, True])
def test_a_folder_holding_other_files_is_refused_and_kept(data, tmp_path, earlier):
    d, refs = data
    out = fresh(d, refs, "a") if earlier else tmp_path / "Documents"
    out.mkdir(exist_ok=True)
    (out / "notes.txt").write_text("the user's own file\n")
    if not earlier:
        (out / "X.csv").write_text("not kinid's\n")
    before = snapshot(out)
    status, _, err = run(d, "b", out)
    line = one_line_error(err, status)
    assert str(out) in line and "notes.txt" in line and "not an earlier result" in line, line
    assert snapshot(out) == before and leftovers(out) == []


def test_an_empty_or_missing_folder_is_written_and_a_file_is_refused(data, tmp_path):
    d, refs = data
    (tmp_path / "empty").mkdir()
    for out in (tmp_path / "empty", tmp_path / "new" / "deeper"):
        status, _, err = run(d, "a", out)
        assert status == 0, err
        assert which(out, refs) == "a"
    (tmp_path / "file").write_text("x")
    status, _, err = run(d, "a", tmp_path / "file")
    one_line_error(err, status)
    assert (tmp_path / "file").read_text() == "x"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty", "file", "new"]


def test_the_library_writes_through_a_link_and_keeps_the_link(data, tmp_path):
    """``write_compensation`` (the library) replaces the folder a link points to; the link stays a link."""
    from kinid.identification import load_fit
    from kinid.identification.compensation.compensate import write_compensation

    d, refs = data
    real = tmp_path / "real"
    real.mkdir()
    (tmp_path / "link").symlink_to(real)
    write_compensation(load_fit(d / "a.json"), tmp_path / "link", fit_path=str(d / "a.json"))
    assert (tmp_path / "link").is_symlink() and snapshot(real) == refs["a"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link", "real"]
