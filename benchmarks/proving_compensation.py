"""Proving ground of ``kinid compensate`` (prints rates; runs under any kinid that has ``compensate``).

Run: ``python benchmarks/proving_compensation.py [--scenarios N] [--layouts M] [--seed S]``.

Scenarios none of the tests describe, drawn from a seeded generator:

- **machine files**: each shipped layout with hidden errors drawn at random — a lead error of every
  linear axis (period 3–25 mm, 0.5–3 µm) with a small quadratic, a periodic error of a rotary
  positioning joint (a whole number of periods per turn, 2–10 µrad), location errors of 5–40 µm /
  µrad, a board set-up of millimetres; 0.5 µm noise on the patent plan; fitted with the true
  structure (the oracle). Each controller file written by ``kinid compensate`` with its defaults is
  read back as its controller reads it (tests/controller_consumers.py, no kinid code) and compared
  with the fitted positioning error inside the measured range; a file the consumer refuses (more
  points than the controller takes) counts as failed.
- **layouts**: machines drawn at random with the URDF builder (axes in random order and direction,
  location errors in random order, chains that end in their set-up joints, continuous rotary
  joints) with random constant errors; ``calibrated.urdf`` must load in plain Pinocchio.

- **travels**: the shipped five-axis machines with their rotary travels redrawn — tight (a few degrees
  beyond the readings), wide (±10 rad, as generated URDFs and many ROS files give them) or continuous —
  measured over part of the range (a tilt over a random sub-range, a table all the way round or over
  part of a turn), with a scale error of a rotary positioning joint (``E<a><a>:poly1``, 0.05–0.5
  µrad/deg, on 60 % of them) besides the errors above. Each controller file is applied by its consumer inside the
  measured range and compared, point by point, with no compensation: a file set (one format's files
  of one scenario) is *worse than none* where at some measured position it leaves more than the error
  itself plus 10 % of the error's RMS (or the format's resolution) — against the fitted model (what
  ``compensate`` checks) and against the truth (the hidden errors). A refusal by ``compensate``
  (exit 2, nothing written) is counted apart.

Printed: per controller format the share of files leaving ≤ 10 % of the error's RMS, the median
and worst share left, files refused; the load rate of calibrated.urdf; for the travels, per format
the rate of file sets worse than none (target 0), the refusals and the modulo and scale decisions.
Against the whole fit, a term kinid leaves out as insignificant (within k = 2) counts as left; "vs
compensated terms" measures the files against what the command compensates (the controller's
interpolation and resolution alone).
"""
from __future__ import annotations

import argparse
import io
import json
import sys
import tempfile
import xml.etree.ElementTree as ET
from contextlib import redirect_stdout
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
from controller_consumers import READERS  # noqa: E402

import kinid  # noqa: E402
from kinid.cli import main as kinid_main  # noqa: E402
from kinid.identification import fit, load_machine, save_fit  # noqa: E402
from kinid.identification.compensation.compensate import positioning_table, write_compensation  # noqa: E402
from kinid.identification.model.effects import default_model, parse_effect  # noqa: E402
from kinid.identification.fitting.fit import FitResult  # noqa: E402
from kinid.identification.model.machine import machine_from_urdf  # noqa: E402
from kinid.identification.fitting.noise import Noise  # noqa: E402
from kinid.identification.fitting.simulate import patent_plan, simulate  # noqa: E402
from kinid.identification.model.urdf_builder import Axis, Fixed, machine_urdf, setup  # noqa: E402
from kinid.urdf import names, path  # noqa: E402

PARSERS = {".comp": "linuxcnc", "_ssfk.lis": "twincat", "_EEC_INI.spf": "sinumerik"}


def hidden_errors(machine, rng) -> dict:
    out = {}
    for e in machine.error_joints:
        if e.location:
            scale = 1000.0 if e.axis == "W" else 20.0
            out[e.code] = float(rng.uniform(-1, 1) * scale * (1.0 if e.unit == "um" else 2.0))
    for a in machine.axes:
        code = f"E{a.name}{a.name}"
        if code not in machine.error_codes:
            continue
        if a.kind == "prismatic":
            out[f"{code}:periodic:{rng.uniform(3.0, 25.0):.3f}"] = list(rng.uniform(-1, 1, 2) * rng.uniform(0.5, 3.0))
            out[f"{code}:poly2"] = [float(rng.uniform(-3e-3, 3e-3)), float(rng.uniform(-2e-5, 2e-5))]
        else:
            out[f"{code}:periodic:{360.0 / rng.integers(1, 9):.6g}"] = list(rng.uniform(-1, 1, 2) * rng.uniform(2, 10))
    return out


def _controller_files(folder: Path, result):
    """(file, format, axis, rotary, 4001 positions over the measured range) of each controller file in ``folder``."""
    for f in sorted(folder.iterdir()):
        fmt = next((v for k, v in PARSERS.items() if f.name.endswith(k)), None)
        if fmt is None:
            continue
        axis = f.name[: f.name.index(next(k for k in PARSERS if f.name.endswith(k)))]
        lo, hi = result.axis_ranges[axis]
        yield f, fmt, axis, result.machine.axis(axis).kind == "revolute", np.linspace(lo, hi, 4001)


def controller_shares(folder: Path, result) -> list:
    """(format, axis, share left or None when the consumer refuses the file)."""
    out = []
    for f, fmt, axis, rotary, x in _controller_files(folder, result):
        model = positioning_table(result, axis, x)
        try:
            reads = READERS[fmt](f.read_text(), rotary)
        except (AssertionError, KeyError, ValueError):
            out.append((fmt, axis, None))
            continue
        to_model = (lambda v: np.radians(v) * 1e6) if rotary else (lambda v: v * 1e3)
        if fmt == "sinumerik":
            err = 0.5 * (model.forward + model.backward)
            left = to_model(reads(x)) - err
        else:
            err = np.concatenate([model.forward, model.backward])
            left = np.concatenate([to_model(reads(x, True)) - model.forward, to_model(reads(x, False)) - model.backward])
        rms_e = float(np.sqrt(np.mean(err ** 2)))
        if rms_e > 0:
            out.append((fmt, axis, float(np.sqrt(np.mean(left ** 2))) / rms_e))
    return out


#: The smallest step of a stored value (µrad for a rotary axis, µm for a linear one), per format.
RESOLUTION = {"linuxcnc": (0.0175, 0.001), "twincat": (1.75, 0.1), "sinumerik": (0.0175, 0.001)}


def travel_scenario(rng, work: Path, k: int):
    """A shipped five-axis machine with redrawn rotary travels, a plan over part of them, and its truth."""
    name = str(rng.choice([n for n in names() if n.startswith("five_axis")]))
    m0 = load_machine(path(name))
    travel = str(rng.choice(["tight", "wide", "continuous"]))
    lo_t, hi_t = -rng.uniform(10.0, 90.0), rng.uniform(10.0, 90.0)
    tilt = tuple(np.linspace(lo_t, hi_t, int(rng.integers(4, 10))))
    if rng.random() < 0.5:
        turn = tuple(np.arange(0.0, 360.0, 360.0 / int(rng.integers(8, 16))))
    else:
        turn = tuple(np.linspace(0.0, rng.uniform(90.0, 300.0), int(rng.integers(4, 12))))
    root = ET.fromstring(path(name).read_text())
    rotary = {a.joint: a for a in m0.axes if a.kind == "revolute"}
    for j in root.findall("joint"):
        if j.get("name") not in rotary:
            continue
        limit = j.find("limit")
        if travel == "continuous":
            j.set("type", "continuous")
            if limit is not None:
                j.remove(limit)
            continue
        if travel == "wide":
            lo, hi = -10.0, 10.0
        else:
            span = tilt + turn
            lo, hi = np.radians(min(span) - rng.uniform(1.0, 20.0)), np.radians(max(span) + rng.uniform(1.0, 20.0))
        if limit is None:
            limit = ET.SubElement(j, "limit", effort="1000", velocity="1")
        limit.set("lower", f"{lo:.6f}")
        limit.set("upper", f"{hi:.6f}")
    file = work / f"t{k}.urdf"
    file.write_text(ET.tostring(root, encoding="unicode"))
    m = load_machine(file)
    truth = hidden_errors(m, rng)
    for a in m.axes:
        if a.kind == "revolute" and f"E{a.name}{a.name}" in m.error_codes and rng.random() < 0.6:
            truth[f"E{a.name}{a.name}:poly1"] = [float(rng.uniform(0.05, 0.5) * rng.choice([-1, 1]))]
    return m, truth, patent_plan(m, tilt_deg=tilt, turn_deg=turn), f"{name}, {travel}"


#: Files worse than none in RMS against the truth, in words (printed after the table).
WORSE_VS_TRUTH = []


def worse_than_none(folder: Path, result, truth_result) -> dict:
    """Per format, over the format's files in ``folder``: (worse than none at some measured position against the
    fitted model, by more than 10 % of the error's RMS or the format's resolution; worse than none in RMS over the
    measured range against the truth, the constant that no fit tells from the set-up and location errors aside)."""
    out = {}
    for f, fmt, axis, rotary, x in _controller_files(folder, result):
        reads = READERS[fmt](f.read_text(), rotary)
        to_model = (lambda v: np.radians(v) * 1e6) if rotary else (lambda v: v * 1e3)
        c = to_model(reads(x))
        t = positioning_table(result, axis, x)
        e = 0.5 * (t.forward + t.backward)
        tol = max(0.10 * float(np.sqrt(np.mean(e ** 2))), RESOLUTION[fmt][0 if rotary else 1])
        flags = [bool(np.max(np.abs(e - c) - np.abs(e)) > tol)]
        t = positioning_table(truth_result, axis, x)
        truth = 0.5 * (t.forward + t.backward)
        truth = truth + np.mean(e - truth)  # a constant positioning error is one with the location errors
        flags.append(bool(np.sqrt(np.mean((truth - c) ** 2)) > np.sqrt(np.mean(truth ** 2))))
        if flags[1]:
            WORSE_VS_TRUTH.append(f"{f.name}: {np.sqrt(np.mean((truth - c) ** 2)):.3g} left of "
                                  f"{np.sqrt(np.mean(truth ** 2)):.3g} {'µrad' if rotary else 'µm'} RMS")
        old = out.get(fmt, (False, False))
        out[fmt] = (old[0] or flags[0], old[1] or flags[1])
    return out


def travels(n: int, rng, work: Path) -> None:
    from dataclasses import replace

    from kinid.identification.compensation.compensate import compensation_model

    sets, refused, said = {}, [], {"modulo": 0, "not modulo (readings round, model not)": 0, "tables": 0}
    for k in range(n):
        m, truth, plan, what = travel_scenario(rng, work, k)
        effects = [parse_effect(e, m) for e in truth]
        theta = np.concatenate([np.atleast_1d(np.asarray(v, float)) for v in truth.values()])
        obs = simulate(m, plan, effects, theta, noise_um=0.5, rng=rng)
        model = list(default_model(m)) + [e for e in effects if e.basis != "constant"]
        result = fit(m, obs, model, noise_um=0.5)
        save_fit(result, work / f"tfit{k}.json")
        out = work / f"tc{k}"
        err = io.StringIO()
        from contextlib import redirect_stderr

        with redirect_stdout(io.StringIO()), redirect_stderr(err):
            status = kinid_main(["compensate", "--fit", str(work / f"tfit{k}.json"), "--out", str(out),
                                 "--format", "linuxcnc", "twincat", "sinumerik"])
        if status != 0:
            refused.append(f"travel {k}: {what}: {err.getvalue().strip()[:160]}")
            continue
        info = json.loads((out / "compensation.json").read_text())
        for t in info["tables"].values():
            said["tables"] += 1
            said["modulo"] += bool(t.get("modulo"))
            said["not modulo (readings round, model not)"] += bool(t.get("not_modulo"))
        p = len(theta)
        truth_result = replace(result, effects=tuple(effects), values=theta, identifiable=np.ones(p, bool),
                               std=np.zeros(p), param_names=tuple(n for e in effects for n in e.param_names()))
        before = len(WORSE_VS_TRUTH)
        for fmt, flags in worse_than_none(out, compensation_model(result).result, truth_result).items():
            sets.setdefault(fmt, []).append(flags)
        if len(WORSE_VS_TRUTH) > before:
            ranges = ", ".join(f"{a} {lo:.4g} .. {hi:.4g}" for a, (lo, hi) in result.axis_ranges.items()
                               if m.axis(a).kind == "revolute")
            WORSE_VS_TRUTH.append(f"  (travel {k}: {what}; measured {ranges}; the fit "
                                  f"{'converged' if result.success else 'did not converge'}: {result.message[:120]})")
    print(f"\n{n} travel scenarios (tight / wide ±10 rad / continuous rotary travels, partial rotary ranges, "
          f"rotary scale errors); file sets worse than none inside the measured range:")
    print(f"{'format':<12} {'file sets':>9} {'at a position, vs fit':>22} {'in RMS, vs truth':>17}")
    for fmt, v in sorted(sets.items()):
        print(f"{fmt:<12} {len(v):>9} {sum(a for a, _ in v) / len(v):>22.1%} {sum(b for _, b in v) / len(v):>17.1%}")
    print(f"compensate refused {len(refused)}/{n}; tables {said['tables']}, modulo {said['modulo']}, "
          f"not modulo for a model that does not repeat every turn {said['not modulo (readings round, model not)']}")
    for line in refused:
        print(f"  refused: {line}")
    for line in WORSE_VS_TRUTH:
        print(f"  worse than none against the truth: {line}")


def random_layout(rng) -> str:
    letters = list(rng.permutation(["X", "Y", "Z", "A", "B", "C"])[: rng.integers(3, 6)])
    chains = {"workpiece": [], "tool": []}
    for k, name in enumerate(letters):
        kind = "revolute" if name in "ABC" else "prismatic"
        chain = chains["workpiece" if rng.random() < 0.5 else "tool"]
        if rng.random() < 0.7:
            chain.append(Fixed(f"f{k}", tuple(rng.uniform(-0.3, 0.3, 3)), tuple(rng.uniform(-0.4, 0.4, 3))))
        chain.append(Axis(name, kind, tuple(np.eye(3)[rng.integers(0, 3)] * rng.choice([-1, 1])),
                          location_errors=tuple(rng.permutation(list("XYZABC"))[: rng.integers(0, 7)]),
                          pdge=bool(rng.random() < 0.6), limit=(-1.0, 1.0) if kind == "prismatic" else (-3.0, 3.0)))
    chains["workpiece"].append(setup("W"))
    chains["tool"] += [Fixed("tool_holder", (0.0, 0.0, -0.1)), setup("T")]
    root = ET.fromstring(machine_urdf("random", chains["workpiece"], chains["tool"]))
    for end in ("workpiece", "tool"):
        if rng.random() < 0.5:
            mount = root.find(f"joint[@name='{end}_mount']")
            inner = mount.find("parent").get("link")
            root.find(f"joint/child[@link='{inner}']").set("link", end)
            root.remove(mount)
            root.remove(root.find(f"link[@name='{inner}']"))
    for j in root.findall("joint"):
        if j.get("type") == "revolute" and j.get("name") in "ABC" and rng.random() < 0.5:
            j.set("type", "continuous")
            j.remove(j.find("limit"))
    return ET.tostring(root, encoding="unicode")


def constant_fit(machine, rng) -> FitResult:
    effects = tuple(default_model(machine))
    p = len(effects)
    v = rng.uniform(-50, 50, p)
    return FitResult(machine=machine, effects=effects, param_names=tuple(e.name for e in effects),
                     units=tuple("µm" if e.unit == "um" else "µrad" for e in effects), values=v, std=np.full(p, 0.1),
                     identifiable=np.ones(p, bool), aliases=(), rank=p, condition_number=1.0, o1=1.0, o3=1.0,
                     residuals_um=None, n_observations=100, rms_um=0.1, noise=Noise(0.1, "given"), dof=300 - p,
                     iterations=1, success=True, message="", axis_ranges={})


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", type=int, default=24)
    ap.add_argument("--layouts", type=int, default=100)
    ap.add_argument("--travels", type=int, default=24, help="scenarios of redrawn rotary travels and ranges")
    ap.add_argument("--seed", type=int, default=2027)
    args = ap.parse_args(argv)
    import pinocchio as pin

    rng = np.random.default_rng(args.seed)
    work = Path(tempfile.mkdtemp())
    shares = {}
    layouts = [n for n in names() if n.startswith("five_axis")]  # the patent plan needs a rotary table or head
    for k in range(args.scenarios):
        m = load_machine(path(layouts[k % len(layouts)]))
        truth = hidden_errors(m, rng)
        effects = [parse_effect(n, m) for n in truth]
        theta = np.concatenate([np.atleast_1d(np.asarray(v, float)) for v in truth.values()])
        obs = simulate(m, patent_plan(m), effects, theta, noise_um=0.5, rng=rng)
        model = list(default_model(m)) + [e for e in effects if e.basis != "constant"]
        result = fit(m, obs, model, noise_um=0.5)
        save_fit(result, work / f"fit{k}.json")
        with redirect_stdout(io.StringIO()):
            status = kinid_main(["compensate", "--fit", str(work / f"fit{k}.json"), "--out", str(work / f"c{k}")])
        if status != 0:
            shares.setdefault("compensate failed", []).append(None)
            continue
        for fmt, axis, share in controller_shares(work / f"c{k}", result):
            shares.setdefault(fmt, []).append(share)
        try:  # a kinid that compensates only the significant terms: the files against what it compensates
            from kinid.identification.compensation.compensate import compensation_model
        except ImportError:
            continue
        for fmt, axis, share in controller_shares(work / f"c{k}", compensation_model(result).result):
            shares.setdefault(f"{fmt} (vs compensated terms)", []).append(share)
    print(f"kinid {kinid.__version__} from {Path(kinid.__file__).parent.parent}; {args.scenarios} machine-file "
          f"scenarios (seed {args.seed}) over {', '.join(layouts)}; default compensate options")
    print(f"{'format':<34} {'files':>5} {'<=10 % left':>11} {'median left':>11} {'worst left':>10} {'refused':>7}")
    for fmt, v in sorted(shares.items()):
        ok = [s for s in v if s is not None]
        print(f"{fmt:<34} {len(v):>5} {sum(s <= 0.10 for s in ok) / len(v):>11.0%} "
              f"{(np.median(ok) if ok else float('nan')):>11.1%} {(max(ok) if ok else float('nan')):>10.1%} "
              f"{len(v) - len(ok):>7}")
    loads = 0
    for k in range(args.layouts):
        text = random_layout(rng)
        folder = work / f"l{k}"
        try:
            m = machine_from_urdf(text, f"<random {k}>")
            with redirect_stdout(io.StringIO()):
                write_compensation(constant_fit(m, rng), folder)
            pin.buildModelFromXML((folder / "calibrated.urdf").read_text())
            loads += 1
        except Exception:  # noqa: BLE001 - a refusal by Pinocchio is the measured outcome
            pass
    print(f"calibrated.urdf loads in plain Pinocchio: {loads}/{args.layouts} random layouts")
    travels(args.travels, rng, work)
    json.dump({k: v for k, v in shares.items()}, open(work / "shares.json", "w"))


if __name__ == "__main__":
    main()
