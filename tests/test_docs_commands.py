"""Every command the README and docs show in a ``sh`` code block runs as written from a fresh clone.

Convention for the docs: a fenced block whose info string is ``sh`` holds
commands a user can copy and run from the top folder of a fresh clone (after
the README's set-up); the blocks of one page run in order, in one copy of the
repository, so a later block may use what an earlier one wrote. Templates
with placeholders (``FIT.json``, ``DIR``) go in ``text`` blocks, which are
not run. What a command prints is shown in a ``text`` block after an
``<!-- output of: COMMAND -->`` marker, checked by ``tests/test_docs_output.py``
(the convention: ``tests/docs_output.py``).

The set-up steps themselves (``python3 -m venv .venv``, ``.venv/bin/pip
install ...``) are what CI does before running the tests; here they are
dropped and ``.venv/bin/`` stands for the environment running the tests.
"""
from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BLOCK = re.compile(r"^```sh[ \t]*\n(.*?)^```", re.S | re.M)
SETUP = re.compile(r"^(python3? -m venv \.venv|\.venv/bin/pip install\b.*)$")


def _pages():
    return [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))


def _commands(text: str):
    """Commands of the ``sh`` blocks of a page, continuation lines joined, set-up steps dropped."""
    out = []
    for block in BLOCK.findall(text):
        joined = re.sub(r"\\\n\s*", " ", block)
        for line in joined.splitlines():
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            parts = [p.strip() for p in line.split("&&")]
            parts = [p for p in parts if not SETUP.match(p)]
            if parts:
                out.append(" && ".join(parts))
    return out


PAGES = [p for p in _pages() if _commands(p.read_text(encoding="utf-8"))]


def _fresh_clone(dest: Path) -> Path:
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True)
    if files.returncode != 0:  # pragma: no cover
        pytest.skip("not a git checkout")
    for name in files.stdout.splitlines():
        src = ROOT / name
        if src.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / name)
    return dest


def test_the_readme_shows_runnable_commands():
    commands = _commands((ROOT / "README.md").read_text(encoding="utf-8"))
    assert any(c.split()[0].endswith("kinid") and " demo" in c for c in commands), commands
    assert any("pytest" in c for c in commands), commands


def _run(command: str, clone: Path, **kwargs) -> subprocess.CompletedProcess:
    """Run one docs command in ``clone`` as a user would, ``.venv/bin/`` standing for the running environment."""
    bindir = Path(sys.executable).parent
    env = dict(os.environ, PATH=f"{bindir}{os.pathsep}{os.environ.get('PATH', '')}", MPLBACKEND="Agg",
               OPENBLAS_NUM_THREADS="1")
    shell = command.replace(".venv/bin/", f"{shlex.quote(str(bindir))}/")
    kwargs.setdefault("stdout", subprocess.PIPE)
    kwargs.setdefault("stderr", subprocess.PIPE)
    return subprocess.run(shell, shell=True, cwd=clone, env=env, text=True, timeout=600, **kwargs)


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_page_commands_run_as_written(page, tmp_path):
    clone = _fresh_clone(tmp_path / "clone")
    for command in _commands(page.read_text(encoding="utf-8")):
        if "pytest" in command:
            # the test command itself: collect only (running the suite inside the suite would recurse)
            command = command + " --collect-only -q"
        out = _run(command, clone)
        assert out.returncode == 0, f"{page.name}: `{command}` exited {out.returncode}:\n{out.stdout[-2000:]}\n{out.stderr[-2000:]}"
