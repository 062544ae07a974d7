"""The house: variants are registries, imports form layers without cycles, modules stay readable.

- Adding an effect basis is one registration (kinid.identification.model.bases): a test-only basis is
  registered here and goes through identify, diagnose and compensate untouched elsewhere. (Adding a
  controller format is tested the same way in test_compensation_files.py.)
- The import graph of the whole package (imports inside functions included, a name taken from a lazy
  front door counted as an import of the module that defines it) has no cycle, and the layers point
  one way: the ground floor and the shipped machine files, then vision, then identification, then
  stages (and the URDF generator), then the command-line roof.
- Inside identification, the sub-packages are layers too (model < data < fitting < diagnosis, planning
  < compensation, reporting < commands), and one meets another only at its front door; no folder of
  the package holds more than 15 modules.
"""
from __future__ import annotations

import ast
import importlib
import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from kinid.cli import main
from kinid.identification import load_machine, save_fit
from kinid.identification.model.bases import BASES, Basis, register_basis
from kinid.identification.fitting.fit import fit, model_effects
from kinid.identification.fitting.simulate import errors_from_mapping, load_plan, simulate
from kinid.urdf import path as urdf_path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = {"kinid": "kinid", "identification": "kinid.identification", "vision": "kinid.vision",
           "stages": "kinid.stages", "urdf": "kinid.urdf"}


def _modules() -> dict:
    out = {}
    for folder, package in FOLDERS.items():
        for f in (ROOT / folder).rglob("*.py"):
            rel = f.relative_to(ROOT / folder).with_suffix("")
            if not (f.parent / "__init__.py").exists():
                continue
            parts = [p for p in rel.parts if p != "__init__"]
            out[".".join([package, *parts])] = f
    return out


def _front_door_sources(modules: dict) -> dict:
    """Package -> {name: module of the package that defines it}, from the ``_SOURCES`` of lazy front doors."""
    out = {}
    for m, f in modules.items():
        if f.name != "__init__.py":
            continue
        for node in ast.parse(f.read_text(encoding="utf-8")).body:
            if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "_SOURCES" for t in node.targets):
                out[m] = {k: f"{m}.{v}" for k, v in ast.literal_eval(node.value).items()}
    return out


def _imports(m: str, f: Path, modules: dict):
    """(package or module imported from, name or None) for every import of module ``m`` (anywhere in the file)."""
    here = m.split(".") if f.name == "__init__.py" else m.split(".")[:-1]
    for node in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            base = ".".join(here[: len(here) - node.level + 1] + ([node.module] if node.module else [])) \
                if node.level else node.module
            for a in node.names:
                yield base, a.name
        elif isinstance(node, ast.Import):
            for a in node.names:
                yield a.name, None


def _graph() -> dict:
    """Module -> the package modules it imports (anywhere in the file; a front door's name -> its module)."""
    modules = _modules()
    sources = _front_door_sources(modules)
    edges = {m: set() for m in modules}
    for m, f in modules.items():
        for base, name in _imports(m, f, modules):
            if name is None:
                target = base
            elif f"{base}.{name}" in modules:
                target = f"{base}.{name}"
            else:
                target = sources.get(base, {}).get(name, base)
            if target in modules and target != m:
                edges[m].add(target)
    return edges


def test_no_import_cycle_in_any_package():
    edges = _graph()
    state, cycles = {}, []

    def visit(m, path):
        state[m] = "open"
        for t in sorted(edges[m]):
            if state.get(t) == "open":
                cycles.append(path[path.index(t):] + [t] if t in path else [m, t])
            elif t not in state:
                visit(t, path + [t])
        state[m] = "done"

    for m in sorted(edges):
        if m not in state:
            visit(m, [m])
    assert not cycles, "import cycles:\n" + "\n".join(" -> ".join(c) for c in cycles)


def _layer(module: str) -> int:
    if module in ("kinid.cli", "kinid.__main__"):
        return 4
    if module == "kinid.urdf.generate" or module.startswith("kinid.stages"):
        return 3
    if module.startswith("kinid.identification"):
        return 2
    if module.startswith("kinid.vision"):
        return 1
    return 0  # the ground floor (kinid.*) and the shipped machine files (kinid.urdf)


def test_layers_point_one_way():
    """ground floor < vision < identification < stages < roof: nothing imports a higher layer."""
    bad = [f"{m} ({_layer(m)}) imports {t} ({_layer(t)})" for m, ts in _graph().items() for t in ts
           if _layer(t) > _layer(m)]
    assert not bad, "\n".join(bad)


def test_identification_and_vision_modules_stay_readable():
    long = {str(f.relative_to(ROOT)): n for folder in ("identification", "vision") for f in (ROOT / folder).rglob("*.py")
            if (n := len(f.read_text(encoding="utf-8").splitlines())) > 500}
    assert not long, f"modules over 500 lines: {long}"


#: The sub-packages of identification and their floors: a sub-package imports only lower floors.
SUB_LAYERS = {"model": 0, "data": 1, "fitting": 2, "diagnosis": 3, "planning": 3, "compensation": 4,
              "reporting": 4, "commands": 5}


def _sub(module: str):
    parts = module.split(".")
    return parts[2] if len(parts) > 2 and parts[:2] == ["kinid", "identification"] else None


def test_identification_is_sub_packages_that_meet_at_front_doors():
    """Every module of identification lives in a sub-package; one imports another only at its front door,
    only names the door lists (``__all__``), and only from a lower floor."""
    modules = _modules()
    subs = {p.name for p in (ROOT / "identification").iterdir() if (p / "__init__.py").exists()}
    assert subs == set(SUB_LAYERS), f"sub-packages {sorted(subs)} against the floors {sorted(SUB_LAYERS)}"
    loose = [f.name for f in (ROOT / "identification").glob("*.py") if f.name != "__init__.py"]
    assert not loose, f"modules outside the sub-packages: {loose}"
    doors = {f"kinid.identification.{s}": importlib.import_module(f"kinid.identification.{s}") for s in subs}
    bad = []
    for m, f in modules.items():
        here = _sub(m)
        if here is None:
            continue
        for base, name in _imports(m, f, modules):
            there = _sub(base)
            if there is None or there == here:
                continue
            if base != f"kinid.identification.{there}" or name is None:
                bad.append(f"{m} imports {base}{'.' + name if name else ''}: not through the front door")
            elif name not in doors[base].__all__:
                bad.append(f"{m} imports {name} from {base}, which its front door does not list")
            elif SUB_LAYERS[there] >= SUB_LAYERS[here]:
                bad.append(f"{m} ({here}, floor {SUB_LAYERS[here]}) imports {base} (floor {SUB_LAYERS[there]})")
    assert not bad, "\n".join(bad)


def test_every_front_door_name_is_defined_where_it_says():
    """A front door's names resolve (the lazy door would otherwise fail only when a name is first used)."""
    for package, names in _front_door_sources(_modules()).items():
        door = importlib.import_module(package)
        for name in names:
            assert getattr(door, name) is not None, f"{package}.{name}"
        assert set(door.__all__) <= set(names) | {n for n in door.__all__ if
                                                   importlib.util.find_spec(f"{package}.{n}") is not None}


def test_no_folder_holds_more_than_fifteen_modules():
    crowded = {str(d.relative_to(ROOT)): n for folder in FOLDERS for d in [ROOT / folder, *(ROOT / folder).rglob("*")]
               if d.is_dir() and (n := len([f for f in d.glob("*.py") if f.name != "__init__.py"])) > 15}
    assert not crowded, f"folders with more than 15 modules: {crowded}"


# --- a basis added by registration alone ----------------------------------------------------------

def _triangle_values(e, q, t, s):
    """A triangle wave of period P: the error of a screw whose lead error grows and shrinks linearly."""
    phase = np.mod(q / e.period, 1.0)
    return (1.0 - 4.0 * np.abs(phase - 0.5)).reshape(-1, 1)


TRIANGLE = Basis(
    kind="triangle", grammar=r"triangle:(?P<period>[0-9]*\.?[0-9]+)", syntax="triangle:<P>", driver="position",
    parse=lambda m, ctx: {"period": float(m.group("period"))}, n_params=lambda e: 1,
    param_names=lambda e: [e.name], param_units=lambda e, u, q: [u], values=_triangle_values,
    describe=lambda e, u: f"triangle wave in {e.axis}, period {e.period:g}{u}")


@pytest.fixture()
def triangle():
    register_basis(TRIANGLE)
    try:
        yield TRIANGLE
    finally:
        BASES.pop("triangle")


def test_a_registered_basis_goes_through_identify_and_compensate(triangle, tmp_path, capsys):
    m = load_machine(urdf_path("five_axis_bc"))
    effects, theta = errors_from_mapping({"EX0C": 12.0, "EXX:triangle:12": [2.5]}, m)
    obs = simulate(m, load_plan("patent", m), effects, theta, noise_um=0.3, rng=np.random.default_rng(4))
    from kinid.identification.data.observations import write_observations

    write_observations(tmp_path / "obs.csv", obs, m)
    assert main(["identify", "--machine", str(urdf_path("five_axis_bc")), "--data", str(tmp_path / "obs.csv"),
                 "--noise-um", "0.3", "--add", "EXX:triangle:12", "--out", str(tmp_path / "fit.json")]) == 0
    params = {p["name"]: p for p in json.loads((tmp_path / "fit.json").read_text())["parameters"]}
    assert params["EXX:triangle:12"]["value"] == pytest.approx(2.5, abs=4 * params["EXX:triangle:12"]["std"])
    assert main(["compensate", "--fit", str(tmp_path / "fit.json"), "--out", str(tmp_path / "comp")]) == 0
    rows = np.loadtxt(tmp_path / "comp" / "X.csv", delimiter=",", skiprows=1)
    x, exx = rows[:, 0], rows[:, 1]
    inside = (x > -60) & (x < 60)
    truth = 2.5 * (1.0 - 4.0 * np.abs(np.mod(x / 12.0, 1.0) - 0.5))
    assert np.abs(exx[inside] - truth[inside]).max() < 0.3
    # the report's words come from the basis too
    fit_result = fit(m, obs, model_effects(m, ["EXX:triangle:12"]), noise_um=0.3)
    save_fit(fit_result, tmp_path / "fit2.json")
    capsys.readouterr()
    assert main(["diagnose", "--fit", str(tmp_path / "fit2.json"), "--data", str(tmp_path / "obs.csv"),
                 "--report", str(tmp_path / "report")]) == 0
    assert "triangle wave in X, period 12 mm" in (tmp_path / "report" / "index.html").read_text()


def test_an_unregistered_basis_is_refused_with_the_known_ones():
    m = load_machine(urdf_path("five_axis_bc"))
    with pytest.raises(Exception, match="expected poly<k>.*periodic:<P>.*local:<step>:<from>:<to>"):
        model_effects(m, ["EXX:triangle:12"])


def test_every_verb_has_a_description_and_every_option_a_help_text():
    """`kinid VERB --help` answers the user's question: what the verb does, and what each option is."""
    import argparse

    from kinid.cli import VERBS, build_parser

    for verb in VERBS:
        parser = build_parser(verb)
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[verb]
        assert sub.description, f"kinid {verb} has no description"
        bare = [a.option_strings[0] if a.option_strings else a.dest for a in sub._actions
                if a.dest != "help" and not a.help]
        assert not bare, f"kinid {verb}: options without help text: {bare}"


def test_results_print_short():
    """repr of a machine, a fit and a diagnosis is one line that says what it is (not the whole URDF)."""
    import numpy as np

    from kinid.identification import default_model, diagnose, fit, load_machine, simulate
    from kinid.identification.fitting.simulate import patent_plan
    from kinid.urdf import path

    machine = load_machine(path("five_axis_bc"))
    effects = default_model(machine)
    obs = simulate(machine, patent_plan(machine), effects, np.zeros(sum(e.n_params for e in effects)), noise_um=1.0,
                   rng=np.random.default_rng(1))
    for thing in (machine, fit(machine, obs), diagnose(machine, obs, effects)):
        text = repr(thing)
        assert len(text) < 200 and "\n" not in text and "<robot" not in text, text


def test_a_name_parsed_once_is_refused_once_its_basis_leaves_the_registry():
    """Effect names are parsed once per machine; a basis taken out of the registry parses no more."""
    from kinid.identification.model.effects import parse_effect

    m = load_machine(urdf_path("five_axis_bc"))
    register_basis(TRIANGLE)
    try:
        assert parse_effect("EXX:triangle:12", m) is parse_effect("EXX:triangle:12", m)
    finally:
        BASES.pop("triangle")
    with pytest.raises(Exception, match="expected poly<k>"):
        parse_effect("EXX:triangle:12", m)


def test_only_the_basis_registry_switches_on_a_basis_kind():
    """No module but kinid.identification.model.bases compares anything with a basis kind or an effect name's
    kind part (``e.basis == "local"``, ``":periodic:" in name``), or keys a table by kinds: what a kind does
    is a field of its Basis."""
    kinds = set(BASES)
    named = [f":{k}" for k in kinds]
    bases_file = ROOT / "identification" / "model" / "bases.py"
    bad = []
    for m, f in _modules().items():
        if f == bases_file or not m.startswith("kinid.identification"):
            continue
        for node in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Compare):
                if any(isinstance(c, ast.Name) and c.id == "BASES" for c in node.comparators):
                    continue  # whether a kind is registered: a question to the registry
                operands = [node.left, *node.comparators]
                strings = [c.value for o in operands for c in ast.walk(o)
                           if isinstance(c, ast.Constant) and isinstance(c.value, str)]
                attrs = [o.attr for o in operands if isinstance(o, ast.Attribute)]
                if any(s in kinds or any(n in s for n in named) for s in strings) and (
                        "basis" in attrs or "kind" not in attrs):
                    bad.append(f"{m}:{node.lineno}: {ast.unparse(node)}")
                elif "basis" in attrs:
                    bad.append(f"{m}:{node.lineno}: {ast.unparse(node)}")
            elif isinstance(node, ast.Dict):
                keys = {k.value for k in node.keys if isinstance(k, ast.Constant) and isinstance(k.value, str)}
                if len(keys & kinds) >= 2:
                    bad.append(f"{m}:{node.lineno}: a table keyed by basis kinds {sorted(keys & kinds)}")
    assert not bad, "switches on a basis kind outside the registry:\n" + "\n".join(bad)


def test_the_architecture_page_is_drawn_from_the_folders():
    """docs/architecture.md has one row per sub-package of identification, on its floor, naming every module."""
    import re

    rows = {}
    for line in (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8").splitlines():
        m = re.match(r"\s*\|\s*(\d+)\s*\|\s*`(\w+)`\s*\|(.*)\|\s*$", line)
        if m:
            rows[m.group(2)] = (int(m.group(1)), set(re.findall(r"`(\w+)`", m.group(3))))
    assert {k: v[0] for k, v in rows.items()} == SUB_LAYERS
    for sub, (_, named) in rows.items():
        modules = {f.stem for f in (ROOT / "identification" / sub).glob("*.py")} - {"__init__"}
        assert modules <= named, f"docs/architecture.md's row of {sub} does not name {sorted(modules - named)}"
