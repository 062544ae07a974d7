"""Start-up: ``kinid VERB --help`` builds its parser without importing the libraries that do the work.

A structural check, not a timing one: each case runs in a fresh Python process and lists the heavy
modules found in ``sys.modules`` after ``kinid VERB --help`` has printed its help. The packages'
front doors (``kinid.identification``, ``kinid.vision``, ``kinid.stages``) import their modules
on first use of a name, so every public name is still there for library users.
"""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from kinid.cli import VERBS

#: What the help of a verb must not import (each costs from 50 ms to several hundred).
HEAVY = ("pinocchio", "casadi", "scipy", "matplotlib", "cv2")

#: Verbs whose help still imports a heavy module (verb -> why); strict xfails, so the test says so
#: when the import is gone and the entry should go too. None left: kinid.stages.dual_axis loads its
#: simulated gantry (Pinocchio) on first use, and its simulate module imports load_machine when a gantry is built.
HEAVY_KNOWN: dict = {}

#: Verbs whose help still imports NumPy (about as long as all of ``kinid --help``), verb -> why; strict
#: xfails like HEAVY_KNOWN. None left: kinid.axis_tables, the stage packages (PEP 562 front doors),
#: their cli modules and kinid.stages.iso230_2 import numpy inside the functions that compute.
NUMPY_KNOWN: dict = {}

HELP = """
import contextlib, io, json, sys
from kinid.cli import main
verb = sys.argv[1]
out = io.StringIO()
with contextlib.redirect_stdout(out):
    try:
        main(([verb] if verb else []) + ["--help"])
    except SystemExit as exc:
        assert exc.code in (0, None), exc.code
assert "usage: kinid" in out.getvalue(), out.getvalue()
print(json.dumps(sorted({m.split(".")[0] for m in sys.modules})))
"""


def _top_level_modules_after_help(verb: str, cwd) -> set:
    out = subprocess.run([sys.executable, "-c", HELP, verb], capture_output=True, text=True, timeout=120, cwd=cwd)
    assert out.returncode == 0, out.stderr
    return set(json.loads(out.stdout))


def _cases(known: dict):
    return [pytest.param(verb, id=verb or "no-verb",
                         marks=[pytest.mark.xfail(reason=known[verb], strict=True)] if verb in known else [])
            for verb in ["", *VERBS]]


@pytest.mark.parametrize("verb", _cases(HEAVY_KNOWN))
def test_help_imports_no_heavy_library(verb, tmp_path):
    found = _top_level_modules_after_help(verb, tmp_path) & set(HEAVY)
    assert not found, f"kinid {verb} --help imports {sorted(found)}"


@pytest.mark.parametrize("verb", _cases(NUMPY_KNOWN))
def test_help_imports_no_numpy(verb, tmp_path):
    assert "numpy" not in _top_level_modules_after_help(verb, tmp_path), f"kinid {verb} --help imports numpy"


def test_packages_import_light_and_keep_every_public_name(tmp_path):
    code = ("import sys, types; import kinid, kinid.identification, kinid.vision, kinid.stages; "
            f"light = sorted(m for m in sys.modules if m.split('.')[0] in {(*HEAVY, 'numpy')!r}); "
            "import kinid.identification.fitting.fit, kinid.identification.diagnosis.diagnose, kinid.identification.fitting.simulate; "
            "names = {p.__name__: [type(getattr(p, n)).__name__ for n in p.__all__] "
            "for p in (kinid, kinid.identification, kinid.vision, kinid.stages)}; "
            "from kinid.identification import fit, diagnose, simulate, urdf_builder; "
            "from kinid.vision import detect_markers, Board; from kinid.stages import uvw; "
            "print(light); print(names['kinid.identification']); "
            "print([isinstance(f, types.FunctionType) for f in (fit, diagnose, simulate)])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    light, identification, functions = out.stdout.splitlines()
    assert light == "[]"
    assert identification.count("'function'") == 14 and identification.count("'module'") == 1  # urdf_builder
    assert functions == "[True, True, True]"


def test_unknown_attribute_is_an_attribute_error():
    import kinid.identification
    import kinid.stages
    import kinid.vision

    for package in (kinid, kinid.identification, kinid.vision, kinid.stages):
        assert not hasattr(package, "no_such_name")


def _modules_after_identify(tmp_path, errors: str, *options) -> set:
    """The modules loaded by ``kinid identify [options]`` in a fresh process, on rows simulated with ``errors``."""
    from kinid.urdf import path

    urdf = str(path("five_axis_bc"))
    (tmp_path / "errors.json").write_text(errors)
    subprocess.run([sys.executable, "-m", "kinid", "simulate", "--machine", urdf, "--errors", "errors.json",
                    "--noise-um", "1", "--out", "obs.csv"], check=True, capture_output=True, timeout=120, cwd=tmp_path)
    code = ("import contextlib, io, json, sys; from kinid.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            f"    rc = main(['identify', '--machine', {urdf!r}, '--data', 'obs.csv', '--noise-um', '1', "
            f"*{list(options)!r}, '--out', 'fit.json'])\n"
            "print(rc); print(json.dumps(sorted(sys.modules)))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    rc, modules = out.stdout.splitlines()
    assert rc == "0" and (tmp_path / "fit.json").exists()
    return set(json.loads(modules))


def test_identify_imports_only_what_the_fit_needs(tmp_path):
    modules = _modules_after_identify(tmp_path, '{"EX0C": 12.0, "EXX:periodic:10": [1.5, -0.8]}')
    # (kinid.identification.fitting.alignment is needed: the pose advice for held parameters solves nominal poses)
    unneeded = {"matplotlib", "cv2", "scipy", "kinid.vision", "kinid.stages", "kinid.identification.diagnosis.diagnose",
                "kinid.identification.diagnosis.selection", "kinid.identification.fitting.simulate", "kinid.identification.planning.design",
                "kinid.identification.reporting.report", "kinid.identification.model.urdf_builder", "kinid.identification.commands.demo"}
    assert not unneeded & modules, f"kinid identify imports {sorted(unneeded & modules)}"


def test_identify_auto_imports_no_optimiser_it_does_not_use(tmp_path):
    """``--auto`` imports no scipy at all: not scipy.optimize (0.16 s; its two bounded searches are
    kinid.identification.diagnosis.periods.bounded_minimum, the same steps, tests/test_period_search.py), nor scipy.special
    (0.1 s; the χ² of thousands of degrees of freedom and the F distribution are kinid.stats's, tests/test_stats.py)."""
    modules = _modules_after_identify(tmp_path, '{"EX0C": 12.0, "EXX:periodic:13.3": [1.5, -0.8]}', "--auto")
    assert json.loads((tmp_path / "fit.json").read_text())["effects"][-1].startswith("EXX:")
    assert "kinid.identification.diagnosis.selection" in modules  # the selection ran
    assert not {"scipy", "matplotlib", "cv2", "kinid.identification.reporting.report"} & modules


def test_stage_packages_import_light_and_keep_every_public_name(tmp_path):
    """The stage packages load their names on first use; ``calibrate`` stays the function after its module loads."""
    code = ("import sys, types, importlib; stages = ('backlash', 'uvw', 'dual_axis', 'contour'); "
            "packages = [importlib.import_module(f'kinid.stages.{s}') for s in stages]; "
            "import kinid.stages.iso230_2, kinid.stages.backlash.cli, kinid.stages.uvw.cli, "
            "kinid.stages.dual_axis.cli, kinid.stages.contour.cli; "
            f"print(sorted(m for m in sys.modules if m.split('.')[0] in {(*HEAVY, 'numpy')!r})); "
            "import kinid.stages.backlash.calibrate, kinid.stages.uvw.calibrate, kinid.stages.dual_axis.calibrate; "
            "print([n for p in packages for n in p.__all__ if not hasattr(p, n)]); "
            "print([p.__name__ for p in packages[:3] if not isinstance(p.calibrate, types.FunctionType)]); "
            "from kinid.stages.backlash.cli import plot_result; from kinid.stages.dual_axis.cli import run_simulation; "
            "print([callable(plot_result), callable(run_simulation)])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines() == ["[]", "[]", "[]", "[True, True]"]
