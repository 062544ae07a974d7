"""Every folder a verb writes is, after a kill, a Ctrl-C, a full disk or a refused write, the earlier result or the
new one, byte for byte.

The verbs and options are taken from the parsers (every output declared a folder); each needs a working call in
``CALLS`` (a verb added without one fails :func:`test_every_folder_output_has_a_call`). For each, a reference run
makes the new result; the earlier one is that result with one file changed (it stays an earlier result of the
command, which may be replaced). A small driver runs the command line with faults put in at chosen points:
SIGKILL before the n-th file of the new folder or half-way through it, before and after the swap and while the
earlier result is removed; SIGINT before a file and at the swap; SIGTERM before a file and the swap; ENOSPC on a write or a file's sync, EROFS and
EACCES. The clock of the reports is fixed, so two runs write the same bytes.
"""
from __future__ import annotations

import argparse
import concurrent.futures
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from kinid.cli import DEFAULT_OUTPUTS, VERBS, build_parser, main
from kinid.urdf import path as urdf_path

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
MACHINE = str(urdf_path("five_axis_bc"))

DRIVER = r'''
"""kinid's command line with faults put in: KT_MODE and KT_ARG (see tests/test_folder_kills.py)."""
import errno
import os
import signal
import sys
import time

# Ctrl-C as at a terminal, even where the suite was started with SIGINT ignored (a shell's background job:
# Python then installs no KeyboardInterrupt handler, and the SIGINT cases would exit 0)
signal.signal(signal.SIGINT, signal.default_int_handler)

import kinid.folders as kd
import kinid.reports.html as kr

MODE = os.environ.get("KT_MODE", "")
ARG = int(os.environ.get("KT_ARG", "0") or 0)
STAGED = ".kinid-new-"
kr.now_utc = lambda: "2026-01-01 00:00:00 UTC"  # two runs, the same bytes


def staged_fd(fd):
    try:
        return STAGED in os.readlink(f"/proc/self/fd/{fd}")
    except OSError:
        return False


def die(sig=signal.SIGKILL):
    os.kill(os.getpid(), sig)
    time.sleep(5)  # SIGINT: the KeyboardInterrupt comes at the next bytecode


class Faulty:
    """A file of the new folder that fails like a full disk, or is killed half-way."""

    def __init__(self, f):
        self._f = f

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._f.close()
        return False

    def write(self, data):
        if MODE == "kill-mid-file":
            self._f.write(data[: len(data) // 2])
            self._f.flush()
            die()
        code = getattr(errno, MODE.rsplit("-", 1)[1])
        raise OSError(code, os.strerror(code))

    def __getattr__(self, name):
        return getattr(self._f, name)


opened = [0]
real_fdopen = os.fdopen


def fdopen(fd, *args, **kwargs):
    f = real_fdopen(fd, *args, **kwargs)
    if staged_fd(fd):
        opened[0] += 1
        if opened[0] == ARG:
            if MODE == "kill-before-file":
                die()
            if MODE == "sigint-before-file":
                die(signal.SIGINT)
            if MODE == "sigterm-before-file":
                die(signal.SIGTERM)
            if MODE == "kill-mid-file" or MODE.startswith("fail-write-"):
                return Faulty(f)
    return f


os.fdopen = fdopen
real_fsync = os.fsync
synced = [0]


def fsync(fd):
    if MODE == "fail-fsync-ENOSPC" and staged_fd(fd):
        synced[0] += 1
        if synced[0] == ARG:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    return real_fsync(fd)


os.fsync = fsync
real_mkdtemp = kd.tempfile.mkdtemp


def mkdtemp(*args, **kwargs):
    if MODE.startswith("fail-mkdir-"):
        code = getattr(errno, MODE.rsplit("-", 1)[1])
        raise OSError(code, os.strerror(code))
    return real_mkdtemp(*args, **kwargs)


kd.tempfile.mkdtemp = mkdtemp
real_swap, real_remove = kd._swap, kd._remove_tree
swapped = [False]


def swap(staged, target):
    if MODE == "kill-before-swap":
        die()
    if MODE == "sigint-before-swap":
        die(signal.SIGINT)
    if MODE == "sigterm-before-swap":
        die(signal.SIGTERM)
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
            p = os.path.join(path, name)
            if os.path.isfile(p):
                os.unlink(p)
        die()
    return real_remove(path)


kd._swap, kd._remove_tree = swap, remove
if MODE == "report-files":  # how many files the new folder gets
    import atexit

    atexit.register(lambda: sys.stderr.write(f"\nKT-FILES {opened[0]}\n"))

from kinid.cli import main  # noqa: E402

sys.exit(main(sys.argv[1:]))
'''


def _verb_parser(verb):
    parser = build_parser(verb)
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[verb]


def folder_outputs() -> list:
    """(verb, option) of every output its parser declares a folder."""
    out = []
    for verb in VERBS:
        sub = _verb_parser(verb)
        outputs = sub.get_default("outputs") or DEFAULT_OUTPUTS
        for a in sub._actions:
            if a.option_strings and outputs.get(a.dest) in ("folder", "replaced folder"):
                out.append((verb, a.option_strings[-1]))
    return out


#: A working call per folder output: the arguments before the folder (``{d}`` is the data folder, ``{u}`` a name
#: of the run's own).
CALLS = {
    ("demo", "--out"): ["demo", "--seed", "3"],
    ("identify", "--report"): ["identify", "--machine", MACHINE, "--data", "{d}/obs.csv", "--add", "EXX:periodic:10",
                               "--out", "{d}/fit_{u}.json"],
    ("diagnose", "--report"): ["diagnose", "--fit", "{d}/fit.json", "--data", "{d}/obs.csv"],
    ("compensate", "--out"): ["compensate", "--fit", "{d}/fit.json"],
    ("verify", "--report"): ["verify", "--fit", "{d}/fit.json", "--data", "{d}/obs.csv"],
    ("backlash", "--tables"): ["backlash", "--data", str(EXAMPLES / "stages" / "backlash" / "log.csv"),
                               "--travel-mm", "0.4"],
    ("backlash", "--report"): ["backlash", "--data", str(EXAMPLES / "stages" / "backlash" / "log.csv"),
                               "--travel-mm", "0.4"],
    ("uvw", "--tables"): ["uvw", "--data", str(EXAMPLES / "stages" / "uvw_moves.csv"), "--lead-um", "2000"],
    ("uvw", "--report"): ["uvw", "--data", str(EXAMPLES / "stages" / "uvw_moves.csv"), "--lead-um", "2000"],
    ("dual-axis", "--report"): ["dual-axis", "--data", str(EXAMPLES / "stages" / "dual_axis.csv"), "--pixel-to-mm",
                                "0.0049931", "0.0002617", "0.0002617", "-0.0049931"],
    ("contour", "--report"): ["contour", "--simulate", "--sim-frames", "16", "--workers", "1"],
    ("contour", "--keep"): ["contour", "--simulate", "--sim-frames", "16", "--workers", "1"],
    ("certificate", "--out"): ["certificate", "--fit", "{d}/fit.json", "--meta", str(EXAMPLES / "certificate_meta.json")],
    ("iso230-2", "--report"): ["iso230-2", "--data", str(EXAMPLES / "x_runs.csv"), "--axis", "X"],
}


def test_every_folder_output_has_a_call():
    declared = set(folder_outputs())
    assert declared == set(CALLS), f"folder outputs without a call: {sorted(declared - set(CALLS))}; " \
                                   f"calls of no folder output: {sorted(set(CALLS) - declared)}"
    assert len(declared) >= 12


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    d = tmp_path_factory.mktemp("kills")
    (d / "driver.py").write_text(DRIVER)
    # a small run keeps each call short (the plan's corners and a few more alignments)
    assert main(["simulate", "--machine", MACHINE, "--errors", str(EXAMPLES / "errors.json"), "--noise-um", "1",
                 "--seed", "5", "--out", str(d / "obs.csv")]) == 0
    assert main(["identify", "--machine", MACHINE, "--data", str(d / "obs.csv"), "--add", "EXX:periodic:10",
                 "--out", str(d / "fit.json")]) == 0
    return d


def _argv(case, d: Path, out: Path) -> list:
    return [a.replace("{d}", str(d)).replace("{u}", out.parent.name) for a in CALLS[case]] + [case[1], str(out)]


def _run(d: Path, case, out: Path, mode: str = "", arg: int = 0, prefix=()):
    env = {**os.environ, "KT_MODE": mode, "KT_ARG": str(arg), "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    p = subprocess.run([*prefix, sys.executable, str(d / "driver.py"), *_argv(case, d, out)], cwd=d, env=env,
                       capture_output=True, text=True, timeout=300)
    return p.returncode, p.stderr


def snapshot(folder: Path) -> dict:
    """Relative path -> bytes of every file under ``folder``."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _leftovers(out: Path) -> list:
    return sorted(p.name for p in out.parent.iterdir() if p.name != out.name)


def _earlier(new: dict) -> tuple:
    """The earlier result: the new one with its largest text file changed (a name kinid owns, other bytes)."""
    texts = [k for k in new if k.endswith((".html", ".csv", ".json", ".txt", ".lis", ".comp", ".urdf"))]
    name = max(texts, key=lambda k: len(new[k]))
    return name, {**new, name: new[name] + b"\n"}


@pytest.fixture(scope="module")
def references(data):
    """Per folder output: (new result, earlier result, changed file, number of files the new folder gets)."""
    refs = {}

    def make(case):
        folder = data / f"ref_{case[0]}_{case[1].strip('-')}"
        status, err = _run(data, case, folder / "out", "report-files")
        assert status == 0, (case, err)
        files = int(err.rsplit("KT-FILES", 1)[1].split()[0])
        again = data / f"again_{case[0]}_{case[1].strip('-')}"
        assert _run(data, case, again / "out")[0] == 0
        new = snapshot(folder / "out")
        assert snapshot(again / "out") == new, f"{case}: two runs wrote different bytes"
        name, earlier = _earlier(new)
        return case, (new, earlier, name, files)

    with concurrent.futures.ThreadPoolExecutor(2) as pool:
        refs.update(pool.map(make, sorted(CALLS)))
    return refs


def _place_earlier(data: Path, case, refs, tag: str) -> Path:
    new, earlier, name, _ = refs[case]
    parent = data / f"w_{tag}_{time.monotonic_ns()}"
    out = parent / "out"
    shutil.copytree(data / f"ref_{case[0]}_{case[1].strip('-')}" / "out", out)
    (out / name).write_bytes(earlier[name])
    assert snapshot(out) == earlier
    return out


def _points(files: int) -> list:
    """At least ten fault points over a run whose new folder gets ``files`` files."""
    spread = sorted({1, 2, max(1, files // 2), files})
    return ([("kill-before-file", n) for n in spread] + [("kill-mid-file", n) for n in (1, files)]
            + [("kill-before-swap", 0), ("kill-after-swap", 0), ("kill-removing-earlier", 0),
               ("sigint-before-file", max(1, files // 2)), ("sigint-before-swap", 0), ("sigint-after-swap", 0),
               ("sigterm-before-file", files), ("sigterm-before-swap", 0)])


#: What each fault leaves: the earlier result or the new one, and the exit status.
EXPECT = {"kill-before-file": ("earlier", -signal.SIGKILL), "kill-mid-file": ("earlier", -signal.SIGKILL),
          "kill-before-swap": ("earlier", -signal.SIGKILL), "kill-after-swap": ("new", -signal.SIGKILL),
          "kill-removing-earlier": ("new", -signal.SIGKILL), "sigint-before-file": ("earlier", 130),
          "sigint-before-swap": ("earlier", 130), "sigint-after-swap": ("new", 130),
          "sigterm-before-file": ("earlier", 143), "sigterm-before-swap": ("earlier", 143)}


@pytest.mark.parametrize("case", sorted(CALLS), ids=lambda c: f"{c[0]} {c[1]}")
def test_killed_or_interrupted_the_folder_is_the_earlier_or_the_new_result(data, references, case):
    new, earlier, _, files = references[case]
    points = _points(files)
    assert len(points) >= 10

    def one(point):
        mode, arg = point
        out = _place_earlier(data, case, references, f"{mode}{arg}")
        status, err = _run(data, case, out, mode, arg)
        return point, out, status, err, snapshot(out) if out.is_dir() else None, _leftovers(out)

    with concurrent.futures.ThreadPoolExecutor(2) as pool:
        results = list(pool.map(one, points))
    kinds = set()
    for (mode, arg), out, status, err, got, left in results:
        which, code = EXPECT[mode]
        assert status == code, (case, mode, arg, status, err)
        assert got == (earlier if which == "earlier" else new), (case, mode, arg, "folder is neither result whole")
        assert all(n.startswith(f".{out.name}.kinid-") for n in left), (case, mode, left)
        kinds.add(which)
        if code in (130, 143):
            said = {130: ": interrupted", 143: ": terminated"}[code]
            assert err.strip().splitlines()[-1] == f"kinid {case[0]}{said}", err
    assert kinds == {"earlier", "new"}
    # the next run into the folder a run killed while removing the earlier result clears what it left
    out = next(out for (mode, _), out, *_ in results if mode == "kill-removing-earlier")
    status, err = _run(data, case, out)
    assert status == 0 and snapshot(out) == new and _leftovers(out) == [], (case, status, err, _leftovers(out))


@pytest.mark.parametrize("case", sorted(CALLS), ids=lambda c: f"{c[0]} {c[1]}")
def test_a_full_disk_or_a_refused_write_is_one_line_and_the_earlier_result_stays(data, references, case):
    _, earlier, _, files = references[case]
    faults = [("fail-write-ENOSPC", 1), ("fail-write-ENOSPC", files), ("fail-fsync-ENOSPC", max(1, files // 2)),
              ("fail-write-EROFS", 1), ("fail-write-EACCES", files), ("fail-mkdir-ENOSPC", 0), ("fail-mkdir-EACCES", 0)]

    def one(fault):
        out = _place_earlier(data, case, references, f"{fault[0]}{fault[1]}")
        status, err = _run(data, case, out, *fault)
        return fault, status, err, snapshot(out), _leftovers(out)

    with concurrent.futures.ThreadPoolExecutor(2) as pool:
        results = list(pool.map(one, faults))
    for fault, status, err, got, left in results:
        lines = [line for line in err.splitlines() if line.strip()]
        assert status == 2 and len(lines) == 1 and "Traceback" not in err, (case, fault, status, err)
        assert lines[0].startswith(f"kinid {case[0]}: "), lines
        reason = {"ENOSPC": "No space left on device", "EROFS": "Read-only file system",
                  "EACCES": "Permission denied"}[fault[0].rsplit("-", 1)[1]]
        assert reason in lines[0], (case, fault, lines[0])
        assert got == earlier and left == [], (case, fault, left)


@pytest.mark.parametrize("case", sorted(CALLS), ids=lambda c: f"{c[0]} {c[1]}")
def test_a_read_only_folder_is_refused_before_the_work_and_kept(data, references, case, tmp_path):
    """A folder the user may not write (mode 0555; run without root's power to write anyway)."""
    from test_folder_outputs import _unprivileged

    prefix = _unprivileged()
    _, earlier, _, _ = references[case]
    out = _place_earlier(data, case, references, "readonly")
    os.chmod(out, 0o555)
    try:
        t0 = time.monotonic()
        status, err = _run(data, case, out, prefix=prefix)
        took = time.monotonic() - t0
    finally:
        os.chmod(out, 0o755)
    lines = [line for line in err.splitlines() if line.strip()]
    assert status == 2 and len(lines) == 1 and "read-only" in lines[0], (case, status, err)
    assert snapshot(out) == earlier
    assert took < 60
