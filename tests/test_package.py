"""The package's edges: one import name, a ground floor, a lazy command-line roof, docs that stand alone."""
from __future__ import annotations

import ast
import importlib
import re
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOMAINS = ("identification", "vision", "stages", "urdf")
FLOOR = ROOT / "kinid"


def _run(code: str, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True, timeout=120)


def test_distribution_installs_one_top_level_name():
    top = metadata.distribution("kinid").read_text("top_level.txt").split()
    assert top == ["kinid"]


@pytest.mark.parametrize("name", DOMAINS)
def test_generic_names_are_not_importable(name, tmp_path):
    # run outside the source tree, where the repository's folders are not on sys.path
    out = _run(f"import {name}", tmp_path)
    assert out.returncode != 0 and "ModuleNotFoundError" in out.stderr


def test_kinid_imports_with_its_version(tmp_path):
    out = _run("import kinid, kinid.identification, kinid.vision, kinid.stages.uvw, kinid.urdf; "
               "print(kinid.__version__)", tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == metadata.version("kinid")


def test_version_option():
    out = subprocess.run([sys.executable, "-m", "kinid", "--version"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and out.stdout.strip() == f"kinid {metadata.version('kinid')}"


def _imports(path: Path):
    """(line, module) of every absolute import in a Python file."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield node.lineno, a.name, ()
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield node.lineno, node.module, tuple(a.name for a in node.names)


def _domain_of(path: Path):
    rel = path.relative_to(ROOT).parts
    return rel[0] if rel[0] in DOMAINS else None


def test_ground_floor_imports_no_domain():
    bad = []
    for f in FLOOR.rglob("*.py"):
        for line, module, _ in _imports(f):
            if re.match(r"kinid\.(identification|vision|stages|urdf)\b", module):
                bad.append(f"{f.relative_to(ROOT)}:{line}: {module}")
    assert not bad, "the ground floor must not import a domain:\n" + "\n".join(bad)


def test_domains_meet_only_at_front_doors():
    """A domain imports another domain only through a package's ``__all__``, never a private module."""
    bad = []
    for domain in DOMAINS:
        for f in (ROOT / domain).rglob("*.py"):
            for line, module, names in _imports(f):
                m = re.match(r"kinid\.(identification|vision|stages|urdf)\b", module)
                if not m or m.group(1) == domain:
                    continue
                try:
                    package = importlib.import_module(module)
                except ImportError as exc:  # pragma: no cover - reported as a failure below
                    bad.append(f"{f.relative_to(ROOT)}:{line}: {module} ({exc})")
                    continue
                public = set(getattr(package, "__all__", ()))
                if not hasattr(package, "__path__") or not set(names) <= public:
                    bad.append(f"{f.relative_to(ROOT)}:{line}: from {module} import {', '.join(names)}"
                               f" (not all in {module}.__all__)")
    assert not bad, "cross-domain imports must use the other package's front door:\n" + "\n".join(bad)


def test_every_public_name_exists():
    for module in ("kinid", "kinid.identification", "kinid.vision", "kinid.stages.backlash", "kinid.stages.uvw",
                   "kinid.stages.dual_axis", "kinid.stages.contour", "kinid.stages.protocols"):
        m = importlib.import_module(module)
        missing = [n for n in m.__all__ if not hasattr(m, n)]
        assert not missing, f"{module}.__all__ names missing attributes: {missing}"


HEAVY = ("cv2", "matplotlib", "kinid.stages.backlash.simulate", "kinid.stages.contour", "kinid.vision")


def test_help_and_identify_do_not_import_heavy_modules(tmp_path):
    code = ("import sys; from kinid.cli import build_parser; build_parser(None); a = set(sys.modules); "
            "build_parser('identify'); b = set(sys.modules); "
            f"print(sorted(m for m in {HEAVY!r} if m in a)); print(sorted(m for m in {HEAVY!r} if m in b))")
    out = _run(code, tmp_path)
    assert out.returncode == 0, out.stderr
    help_mods, identify_mods = out.stdout.splitlines()
    assert help_mods == "[]"
    assert identify_mods == "[]"


def test_every_verb_is_registered_by_its_module():
    from kinid.cli import VERBS, build_parser

    for verb, spec in VERBS.items():
        parser = build_parser(verb)
        sub = next(a for a in parser._actions if a.dest == "verb")
        assert verb in sub.choices
        # the module's parser is the real one (it has options beyond --help)
        assert len(sub.choices[verb]._actions) > 1, f"{verb}: module {spec.module} registered no options"


def test_unknown_verb_is_one_line_exit_2():
    out = subprocess.run([sys.executable, "-m", "kinid", "no-such-verb"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 2
    assert "unknown verb 'no-such-verb'" in out.stderr and "Traceback" not in out.stderr


def test_generate_honours_help_and_writes_only_where_asked(tmp_path):
    shipped = {p.name: p.read_bytes() for p in (ROOT / "urdf").glob("*.urdf")}
    out = subprocess.run([sys.executable, "-m", "kinid.urdf.generate", "--help"], capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 0 and "--out" in out.stdout
    out = subprocess.run([sys.executable, "-m", "kinid.urdf.generate", "--out", str(tmp_path)], capture_output=True,
                         text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    written = sorted(p.name for p in tmp_path.glob("*.urdf"))
    assert written == ["five_axis_ac.urdf", "five_axis_bc.urdf", "five_axis_bhead_c.urdf"]
    for name in written:  # the shipped files are what the builder writes
        assert (tmp_path / name).read_bytes() == shipped[name]
    assert {p.name: p.read_bytes() for p in (ROOT / "urdf").glob("*.urdf")} == shipped


# ---- the repository stands alone ------------------------------------------------------------------

def _tracked_files():
    out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True)
    if out.returncode != 0:  # pragma: no cover - not a git checkout (an sdist)
        pytest.skip("not a git checkout")
    return [ROOT / f for f in out.stdout.split() if (ROOT / f).is_file()]


FORBIDDEN = re.compile(r"INTERFACES\.md|STYLE\.md|shared/seeds|\bseed 00\d|\b[Pp]atent 00\d|\b[Ii]ssue \d+\b"
                       r"|/work/|/home/\w+/|/Users/\w+/|[A-Z]:\\\\Users")


def test_no_reference_outside_the_repository():
    bad = []
    for f in _tracked_files():
        if f.suffix in (".png", ".pdf", ".jpg", ".tif", ".tiff", ".mp4", ".avi") or f.name == "test_package.py":
            continue
        try:
            text = f.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        for i, line in enumerate(text.splitlines(), 1):
            if FORBIDDEN.search(line):
                bad.append(f"{f.relative_to(ROOT)}:{i}: {line.strip()[:100]}")
    assert not bad, "references that mean nothing to a user:\n" + "\n".join(bad)


LINK = re.compile(r"\]\(([^)#\s]+)(#[^)]*)?\)")
PATH_REF = re.compile(r"(?<![\w/.-])((?:docs|examples|urdf|benchmarks|tests)/[\w./-]*\w)")


def _anchors(md: Path) -> set:
    """The anchors a markdown page's headings get where it is rendered (GitHub's rule: lower case, punctuation
    other than hyphens dropped, spaces to hyphens)."""
    out, fenced = set(), False
    for line in md.read_text(encoding="utf-8").splitlines():
        fenced ^= line.startswith("```")
        if line.startswith("#") and not fenced:
            out.add(re.sub(r"[^\w\- ]", "", line.lstrip("#").strip().lower()).replace(" ", "-"))
    return out


def test_docs_links_and_file_references_resolve():
    """Every markdown link (and the heading it points to) and every ``docs/…``, ``examples/…`` path named in the
    repository exists."""
    bad = []
    for f in _tracked_files():
        if f.suffix not in (".md", ".py", ".toml", ".urdf") or f.name == "test_package.py":
            continue
        text = f.read_text(encoding="utf-8")
        if f.suffix == ".md":
            for m in LINK.finditer(text):
                target = m.group(1)
                if re.match(r"[a-z]+:", target):
                    continue  # a web address
                if not (f.parent / target).exists():
                    bad.append(f"{f.relative_to(ROOT)}: link {target}")
                elif m.group(2) and target.endswith(".md") and m.group(2)[1:] not in _anchors(f.parent / target):
                    bad.append(f"{f.relative_to(ROOT)}: link {target}{m.group(2)} (no such heading)")
        for m in PATH_REF.finditer(text):
            ref = m.group(1)
            if text[m.end():m.end() + 1] in ("*", "<", "{") or ref.endswith("/"):
                continue
            if not (ROOT / ref).exists() and not (f.parent / ref).exists():
                bad.append(f"{f.relative_to(ROOT)}: path {ref}")
    assert not bad, "references that do not resolve inside the repository:\n" + "\n".join(sorted(set(bad)))


def test_library_errors_name_the_argument_and_the_cli_names_the_option(tmp_path):
    """One mapping from argument to option: the library says ``n_targets``, the command line ``--targets``."""
    from kinid.errors import DataError
    from kinid.stages.backlash import plan_moves

    with pytest.raises(DataError, match=r"^n_targets must be an integer >= 1, got 0$"):
        plan_moves(0.8, 2.0, n_targets=0)
    out = subprocess.run([sys.executable, "-m", "kinid", "backlash", "--simulate", "--targets", "0"],
                         capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert out.returncode == 2
    assert out.stderr.strip() == "kinid backlash: --targets must be an integer >= 1, got 0"


def test_front_door_names_stay_functions_after_submodule_imports(tmp_path):
    """``fit``, ``diagnose`` and ``simulate`` are modules and functions; the front door gives the functions."""
    out = _run("import types, kinid.identification.fitting.fit, kinid.identification.diagnosis.diagnose, kinid.identification.fitting.simulate; "
               "from kinid.identification import fit, diagnose, simulate; "
               "print(all(callable(f) and not isinstance(f, types.ModuleType) for f in (fit, diagnose, simulate)))",
               tmp_path)
    assert out.returncode == 0 and out.stdout.strip() == "True", out.stderr
