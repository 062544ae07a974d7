"""Shared test set-up: one BLAS thread for the numpy work outside kinid.threads (as the command line does), Agg plots,
and the two tiers of the suite.

The tiers: ``pytest`` alone runs the fast tier (the README's command, a few minutes); ``KINID_TESTS=all`` (or
``CI=true``, as ``.ci/run`` sets) runs everything. A test is in the slow tier when it is marked ``slow`` or its
node id starts with a line of ``tests/slow_tests.txt`` (the tests measured longest; the list, not the files, so
a measurement can move a test without editing it). The slow tests keep their assertions; they run in CI.
"""
import os
from pathlib import Path

import pytest

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")

_SLOW_LIST = Path(__file__).with_name("slow_tests.txt")


def _slow_prefixes() -> tuple:
    lines = _SLOW_LIST.read_text(encoding="utf-8").splitlines() if _SLOW_LIST.exists() else []
    return tuple(line.strip() for line in lines if line.strip() and not line.lstrip().startswith("#"))


def all_tiers() -> bool:
    """Whether this run is the whole suite (CI) rather than the fast tier."""
    return os.environ.get("KINID_TESTS", "").lower() == "all" or os.environ.get("CI", "").lower() in ("1", "true")


def pytest_collection_modifyitems(config, items):
    prefixes = _slow_prefixes()
    for item in items:
        if prefixes and item.nodeid.startswith(prefixes):
            item.add_marker(pytest.mark.slow)
    if all_tiers() or config.getoption("-m"):  # an explicit -m chooses for itself
        return
    slow = [item for item in items if item.get_closest_marker("slow")]
    if slow:
        config.hook.pytest_deselected(items=slow)
        items[:] = [item for item in items if not item.get_closest_marker("slow")]
        config._kinid_slow = len(slow)


def pytest_report_header(config):
    return ("tests: all tiers (KINID_TESTS=all or CI)" if all_tiers()
            else "tests: the fast tier (KINID_TESTS=all runs the slow tests too, as CI does)")


def pytest_terminal_summary(terminalreporter, config):
    n = getattr(config, "_kinid_slow", 0)
    if n:
        terminalreporter.write_line(f"{n} slow tests not run (the fast tier); KINID_TESTS=all runs them, as CI does")


@pytest.fixture(scope="session")
def ur_arm(tmp_path_factory):
    """The six-axis arm of examples/ur_like.urdf as ``kinid model`` makes it (base ``world``, tool ``wrist_3_link``):
    (URDF path, Machine). Built once for the tests of instrument exports, stated std and several targets."""
    from kinid.cli import main
    from kinid.identification.model import load_machine

    urdf = tmp_path_factory.mktemp("ur_arm") / "arm.urdf"
    assert main(["model", "--urdf", str(Path(__file__).resolve().parents[1] / "examples" / "ur_like.urdf"), "--base",
                 "world", "--tool", "wrist_3_link", "--out", str(urdf)]) == 0
    return urdf, load_machine(urdf)
