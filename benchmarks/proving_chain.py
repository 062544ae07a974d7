"""Proving ground of the image chain: the laser beside the camera against the laser on its axis, every five-axis layout.

Run: ``python benchmarks/proving_chain.py [--scenarios N] [--seed S] [--layouts L ...] [--lens telecentric pinhole]
[--jobs J] [--json OUT]``; ``--only ID ... [--keep DIR]`` runs those scenarios alone (an id is the seed printed
first on its line; give the ``--layouts`` and ``--lens`` of the run that drew it) and keeps each run's files.

Each scenario is drawn from a seeded generator (:func:`draw`), as real set-ups are:

- **a machine**: a shipped five-axis layout (B/C, A/C, B-head + C), its truth plain numpy on the URDF text
  (benchmarks/proving_truth.py, no kinid kinematics); the location errors of its tilting and table axes
  (``E?0<axis>``) 10–40 µm / µrad each, the tool length EZ0T 5–40 µm, the camera turned on the tool (EC0T,
  0.5–3 mrad either way), and ONE hidden position-dependent effect (a lead error, a straightness, a sag, a local
  bump or an error of one axis growing with another's position: proving_ground.hidden_effects);
- **the board**: laid by hand, placed 10–40 µm off in x, y, z, tilted 0–1 mrad about a random horizontal line and
  turned ±10 mrad (the URDF's board joints EX0W … EC0W);
- **the sensor**: a telecentric lens (``pixel_mm``) or a calibrated pinhole camera (benchmarks/camera_render.py),
  and a laser 0–30 mm beside the camera in any direction, its offset given as ``kinid sensor`` measures it (in the
  machine's axes with every axis at 0, the camera's turn EC0T included);
- **a plan**: 3 tilts × 6 table angles (staggered 20° per tilt) × 4 marks = 72 images, the machine stopped
  ~0.1 mm from each mark, readings with 0.5 µm noise, the laser with 0.5 µm.

Its images are rendered ONCE (benchmarks/camera_render.py's ray tracer) and the chain — ``kinid observe``,
``kinid identify --auto`` (which, with the laser beside the camera, judges ``mark_dz_mm`` again with the board
pose it fits), ``kinid compensate`` — runs twice on them: with the laser on the camera's axis and with the drawn
offset; only the laser's readings (and the sensor file's offset) differ. Held-out error: 24 random poses (tilt
and table angle within the plan's range, board points within its marks) commanded by the compensated machine
(calibrated.urdf and its tables in plain Pinocchio, tests/plain_machine.py), the 3-D distance between the true
tool point and the true mark. A scenario passes when the offset run's held-out error is ≤ 1.5× the on-axis
run's, and the offset run adds no effect the truth lacks: none on an error joint the truth leaves at zero unless it names an axis the
hidden effect involves (a lead of Y fitted as a periodic pitch of Y, EAY, is the same error seen through its lever).

A scenario whose on-axis run is refused (a command exits 2) has no reference: it is counted apart ("no reference"),
neither within 1.5× nor beyond, and left out of the rates.

Printed: each scenario's figures, then per layout and lens the pass rate and the medians (held-out on axis, with
the offset, their ratio; uncompensated) over the scenarios judged, and each failure's and unjudged scenario's
figures.
"""
from __future__ import annotations

import argparse
import contextlib
import csv
import io
import json
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(1, str(ROOT / "tests"))
import camera_render as cam  # noqa: E402
import proving_truth as truth  # noqa: E402
from proving_ground import _named_axes, hidden_effects  # noqa: E402

LAYOUTS = ("five_axis_bc", "five_axis_ac", "five_axis_bhead_c")
LENSES = ("telecentric", "pinhole")
HIDDEN_KINDS = ("lead", "straightness", "sag", "bump", "cross-axis")
LASER_MAX_MM = 30.0
TILTS_DEG = (-40.0, 0.0, 40.0)
TURNS = 6
STAGGER_DEG = 20.0
MARKS_MM = ((40.0, 40.0), (-40.0, 40.0), (-40.0, -40.0), (40.0, -40.0))
HELD_OUT = 24
STOP_MM = 0.1
READING_NOISE_UM = LASER_NOISE_UM = 0.5
RATIO_LIMIT = 1.5
NO_REFERENCE = "no reference"  # the on-axis run refused: the scenario is judged neither within nor beyond


# -- the drawn scenario --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Scenario:
    seed: int
    layout: str
    lens: str
    tilt: str  # the tilting axis's joint name
    table: str  # the table axis's (it turns all the way round)
    constants: dict  # error joint -> µm / µrad
    hidden: object  # proving_ground.Hidden: joint, callable(readings, t) -> µm / µrad
    laser_offset_mm: tuple  # in the tool's x, y (where the laser is)

    def errors(self, readings: dict, n: int) -> dict:
        """Error-joint values (µm, µrad), arrays (n,), at the readings (dict axis -> (n,) mm / deg)."""
        out = {k: np.full(n, v) for k, v in self.constants.items()}
        extra = np.asarray(self.hidden(readings, np.zeros(n)), float) * np.ones(n)
        out[self.hidden.joint] = out.get(self.hidden.joint, 0.0) + extra
        return out


def _machine(layout: str) -> truth.TrueMachine:
    from kinid.urdf import path

    return truth.read_urdf(Path(path(layout)).read_text())


def rotary_axes(tm) -> tuple:
    """(tilting axis, table axis): the table is the rotary axis that turns all the way round."""
    rotary = [a for a in tm.motion if tm.kind(a) != "prismatic"]
    table = [a for a in rotary if not np.isfinite(tm.limits[a][0]) or tm.limits[a][1] - tm.limits[a][0] >= 359.0]
    tilt = [a for a in rotary if a not in table]
    if len(table) != 1 or len(tilt) != 1:
        raise ValueError(f"not a five-axis layout with a tilt and a turning table: rotary axes {rotary}")
    return tilt[0], table[0]


def plan_presets(tilt: str, table: str) -> tuple:
    """(presets dict axis -> (n,) deg, marks (n, 3) mm): tilt-major, the table angles turned STAGGER_DEG per tilt."""
    rows = [(b, k * STAGGER_DEG + c, m) for k, b in enumerate(TILTS_DEG) for c in np.arange(TURNS) * 360.0 / TURNS
            for m in MARKS_MM]
    presets = {tilt: np.array([r[0] for r in rows]), table: np.array([r[1] for r in rows])}
    return presets, np.array([[*r[2], 0.0] for r in rows])


def nominal_readings(tm, presets: dict, marks_mm) -> dict:
    """Readings that put the NOMINAL tool point on each mark at the preset rotary angles."""
    n = len(marks_mm)
    start = dict(presets)
    start.update({a: np.zeros(n) for a in tm.motion if tm.kind(a) == "prismatic"})
    return truth.align_linear(tm, start, marks_mm)


def draw(seed: int, layouts=LAYOUTS, lenses=LENSES) -> Scenario:
    rng = np.random.default_rng(seed)
    layout = str(layouts[rng.integers(len(layouts))])
    lens = str(lenses[rng.integers(len(lenses))])
    tm = _machine(layout)
    tilt, table = rotary_axes(tm)

    def signed(lo, hi):
        return float(rng.uniform(lo, hi) * rng.choice([-1, 1]))

    constants = {j: signed(10.0, 40.0) for j in tm.errors if j[2] == "0" and j[3:] in (tilt, table)}
    constants["EZ0T"] = signed(5.0, 40.0)
    constants["EC0T"] = signed(500.0, 3000.0)  # the camera turned on the tool
    tilt_urad, line = rng.uniform(0.0, 1000.0), rng.uniform(0.0, 2 * np.pi)
    constants.update({"EX0W": signed(10, 40), "EY0W": signed(10, 40), "EZ0W": signed(10, 40),
                      "EA0W": float(tilt_urad * np.cos(line)), "EB0W": float(tilt_urad * np.sin(line)),
                      "EC0W": float(rng.uniform(-1e4, 1e4))})
    presets, marks = plan_presets(tilt, table)
    readings = nominal_readings(tm, presets, marks)
    ranges = {a: (float(np.min(v)), float(np.max(v))) for a, v in readings.items()}
    hidden = []
    while not hidden:
        hidden = hidden_effects(tm, str(HIDDEN_KINDS[rng.integers(len(HIDDEN_KINDS))]), rng, ranges)
    radius, angle = LASER_MAX_MM * np.sqrt(rng.uniform()), rng.uniform(0, 2 * np.pi)
    offset = (float(radius * np.cos(angle)), float(radius * np.sin(angle)))
    return Scenario(seed, layout, lens, tilt, table, constants, hidden[0], offset)


# -- the truth ------------------------------------------------------------------------------------------------
def frames(sc: Scenario, tm, readings: dict):
    """Workpiece and tool frames in the machine frame on the true machine: (pw (n, 3) mm, Rw, pt (n, 3) mm, Rt)."""
    n = len(next(iter(readings.values())))
    values = truth.joint_values(tm, readings, sc.errors(readings, n))
    Rw, pw = truth._pose(tm, "workpiece", values, n)
    Rt, pt = truth._pose(tm, "tool", values, n)
    return pw * 1e3, Rw, pt * 1e3, Rt


def laser_as_measured(sc: Scenario, tm) -> list:
    """The laser's offset as ``kinid sensor`` measures it: in machine axes with every axis at 0 (EC0T turns it)."""
    _, _, _, Rt = frames(sc, tm, {a: np.zeros(1) for a in tm.motion})
    return [float(v) for v in (Rt[0] @ np.array([*sc.laser_offset_mm, 0.0]))[:2]]


def write_run(folder: Path, sc: Scenario, tm, rng) -> dict:
    """Render the images once; two run logs (laser on the camera's axis, laser at the offset) and two sensor files
    that differ only in the laser. Returns the case -> (log, sensor) paths."""
    import cv2

    camera = None if sc.lens == "telecentric" else cam.PINHOLE
    (folder / "images").mkdir(parents=True, exist_ok=True)
    presets, marks = plan_presets(sc.tilt, sc.table)
    nominal = nominal_readings(tm, presets, marks)
    linear = sorted(a for a in tm.motion if tm.kind(a) == "prismatic")
    n = len(marks)
    true = {a: nominal[a] + (rng.normal(0.0, STOP_MM, n) if a in linear else 0.0) for a in tm.motion}
    pw, Rw, pt, Rt = frames(sc, tm, true)
    rows = {"axis": [], "offset": []}
    for k in range(n):
        img, on_axis = cam.render_at(pw[k], Rw[k], pt[k], Rt[k], rng, camera=camera)
        beside = cam.laser_mm(pw[k], Rw[k], pt[k], Rt[k], sc.laser_offset_mm)
        name = f"images/{k:03d}.png"
        cv2.imwrite(str(folder / name), img, [cv2.IMWRITE_PNG_COMPRESSION, 1])
        logged = [f"{true[a][k] + rng.normal(0.0, READING_NOISE_UM * 1e-3):.6f}" for a in linear]
        rotary = [f"{true[a][k]:.6f}" for a in (sc.tilt, sc.table)]
        laser_noise = rng.normal(0.0, LASER_NOISE_UM * 1e-3)  # the same draw: only the beam's place differs
        rows["axis"].append([name, *logged, *rotary, f"{on_axis + laser_noise:.6f}"])
        rows["offset"].append([name, *logged, *rotary, f"{beside + laser_noise:.6f}"])
    header = ["image", *(f"{a.lower()}_mm" for a in linear), f"{sc.tilt.lower()}_deg", f"{sc.table.lower()}_deg",
              "laser_mm"]
    cam.write_setup_files(folder, camera)
    sensor = json.loads((folder / "sensor.json").read_text())
    out = {}
    for case, extra in (("axis", {}), ("offset", {"laser_offset_mm": laser_as_measured(sc, tm)})):
        with open(folder / f"log_{case}.csv", "w", newline="") as f:
            csv.writer(f).writerows([header, *rows[case]])
        (folder / f"sensor_{case}.json").write_text(json.dumps({**sensor, **extra}))
        out[case] = (folder / f"log_{case}.csv", folder / f"sensor_{case}.json")
    return out


def held_out_poses(sc: Scenario, tm, rng) -> tuple:
    """(rotary angles dict axis -> (n,) deg, board points (n, 3) mm, nominal readings): within the plan's range."""
    half = max(abs(m) for mark in MARKS_MM for m in mark)
    angles = {sc.tilt: rng.uniform(min(TILTS_DEG), max(TILTS_DEG), HELD_OUT), sc.table: rng.uniform(0, 360, HELD_OUT)}
    points = np.column_stack([rng.uniform(-half, half, (HELD_OUT, 2)), np.zeros(HELD_OUT)])
    return angles, points, nominal_readings(tm, angles, points)


def held_out_um(sc: Scenario, tm, machine, poses) -> float:
    """RMS 3-D distance (µm) between the true tool point and the true mark when ``machine`` (a PlainMachine: the
    compensated or the nominal one) commands the linear axes to put its tool point on the mark."""
    angles, points, nominal = poses
    linear = sorted(a for a in tm.motion if tm.kind(a) == "prismatic")
    errors = []
    for k in range(len(points)):
        fixed = {a: float(v[k]) for a, v in angles.items()}
        r = machine.solve(points[k], fixed, solve=tuple(linear), start=[nominal[a][k] for a in linear])
        readings = {a: np.atleast_1d(float(r[a])) for a in tm.motion}
        pw, Rw, pt, _ = frames(sc, tm, readings)
        errors.append(np.linalg.norm(Rw[0].T @ (pt[0] - pw[0]) - points[k]) * 1e3)
    return float(np.sqrt(np.mean(np.square(errors))))


# -- the chain, twice ------------------------------------------------------------------------------------------
def _kinid(*argv) -> str:
    from kinid.cli import main as kinid_main

    said, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(said), contextlib.redirect_stderr(err):
        status = kinid_main([str(a) for a in argv])
    if status != 0:
        raise ChainError(f"kinid {argv[0]} exited {status}: {err.getvalue().strip().splitlines()[-1:]}")
    return said.getvalue()


class ChainError(RuntimeError):
    """A command of the chain refused the run (exit status 2): the scenario fails with its message."""


def chain(folder: Path, machine: str, log: Path, sensor: Path, case: str) -> dict:
    """observe, identify --auto, compensate: the fit's effects and board-pose record, and the compensation folder."""
    obs, fit_path, comp = folder / f"obs_{case}.csv", folder / f"fit_{case}.json", folder / f"comp_{case}"
    _kinid("observe", "--machine", machine, "--board", folder / "board.json", "--sensor", sensor, "--data", log,
           "--out", obs)
    _kinid("identify", "--machine", machine, "--data", obs, "--auto", "--out", fit_path)
    _kinid("compensate", "--fit", fit_path, "--out", comp, "--step-mm", "0.5")
    fit = json.loads(fit_path.read_text())
    return {"effects": list(fit["effects"]), "board_pose": fit.get("board_pose"), "comp": comp}


def run(seed: int, layouts=LAYOUTS, lenses=LENSES, keep=None) -> dict:
    """One scenario: drawn, rendered once, the chain twice; its record (figures and verdict). ``keep``: a folder to
    write the run into and leave (images, logs, observations, fits, compensations), else a temporary one."""
    from threadpoolctl import threadpool_limits

    from kinid.identification import load_machine
    from kinid.identification.model.effects import default_model
    from kinid.urdf import path
    from plain_machine import PlainMachine

    started = time.perf_counter()
    sc = draw(seed, layouts, lenses)
    tm = _machine(sc.layout)
    rng = np.random.default_rng([seed, 1])
    machine = str(path(sc.layout))
    kin = load_machine(machine)
    default = {e.name for e in default_model(kin)}
    in_truth = {j for j, v in sc.constants.items() if v} | {sc.hidden.joint}
    with threadpool_limits(1), (contextlib.nullcontext(keep) if keep else tempfile.TemporaryDirectory()) as tmp:
        folder = Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        files = write_run(folder, sc, tm, rng)
        poses = held_out_poses(sc, tm, np.random.default_rng([seed, 2]))
        rec = {"seed": seed, "layout": sc.layout, "lens": sc.lens, "laser_offset_mm": list(sc.laser_offset_mm),
               "laser_mm": float(np.hypot(*sc.laser_offset_mm)), "hidden": f"{sc.hidden.kind} {sc.hidden.joint}",
               "ec0t_urad": sc.constants["EC0T"],
               "board_tilt_urad": float(np.hypot(sc.constants["EA0W"], sc.constants["EB0W"])),
               "board_turn_urad": sc.constants["EC0W"],
               "uncompensated_um": held_out_um(sc, tm, PlainMachine(urdf=machine), poses)}
        for case, (log, sensor) in files.items():
            try:
                got = chain(folder, machine, log, sensor, case)
            except ChainError as exc:  # a refusal is a failure of the chain, recorded with its message
                rec[case] = {"held_out_um": float("inf"), "added": [], "spurious": [], "board_pose": None,
                             "refused": str(exc)}
                continue
            added = [e for e in got["effects"] if e not in default]
            rec[case] = {"held_out_um": held_out_um(sc, tm, PlainMachine(got["comp"]), poses), "added": added,
                         "spurious": [e for e in added if e.split(":")[0] not in in_truth
                                      and not _named_axes(e, kin) & set(sc.hidden.axes)],
                         "board_pose": got["board_pose"]}
    rec.update(judge(rec["axis"], rec["offset"]))
    rec["seconds"] = time.perf_counter() - started
    return rec


def judge(axis: dict, offset: dict) -> dict:
    """The verdict on a scenario from its on-axis and offset runs' records: ``ratio`` (offset held-out error over the
    on-axis one), ``judged`` — "within" (≤ RATIO_LIMIT), "beyond", or "no reference" when the on-axis run was refused
    (no evidence either way: its error is no number to divide by, neither within nor beyond) — ``pass`` (within and
    no effect the truth lacks) and ``pass_laser`` (within and no such effect the on-axis run does not add too)."""
    if "refused" in axis:
        return {"ratio": float("nan"), "judged": NO_REFERENCE, "pass": False, "pass_laser": False}
    ratio = offset["held_out_um"] / max(axis["held_out_um"], 1e-9)  # an offset run refused: inf, beyond
    within = bool(ratio <= RATIO_LIMIT)
    # the laser's own share: what the offset run does worse than the on-axis run of the same images
    return {"ratio": float(ratio), "judged": "within" if within else "beyond",
            "pass": within and not offset["spurious"],
            "pass_laser": within and set(offset["spurious"]) <= set(axis["spurious"])}


# -- reports ----------------------------------------------------------------------------------------------------
def line(rec: dict) -> str:
    bp = rec["offset"]["board_pose"] or {}
    return (f"seed {rec['seed']:<8} {rec['layout']:<18} {rec['lens']:<11} laser {rec['laser_mm']:5.1f} mm "
            f"EC0T {rec['ec0t_urad']:6.0f} µrad board tilt {rec['board_tilt_urad']:4.0f} turn {rec['board_turn_urad']:6.0f} "
            f"{rec['hidden']:<22} held-out on axis {rec['axis']['held_out_um']:6.3f} offset {rec['offset']['held_out_um']:6.3f} "
            f"µm (×{rec['ratio']:.2f}; uncompensated {rec['uncompensated_um']:6.1f}) passes {bp.get('passes', '-')} "
            f"added {rec['offset']['added'] or '-'} / on axis {rec['axis']['added'] or '-'} "
            f"{_verdict(rec)} {rec['seconds']:.0f} s")


def _verdict(rec: dict) -> str:
    return "NO REFERENCE" if rec.get("judged") == NO_REFERENCE else "PASS" if rec["pass"] else "FAIL"


def summarise(records) -> None:
    """Per class the rates over the scenarios judged (those whose on-axis run was refused counted apart, "no ref"),
    the medians, and each failure's and each unjudged scenario's figures."""
    groups = {}
    for rec in records:
        for key in ("all", f"{rec['layout']} {rec['lens']}", rec["layout"], rec["lens"]):
            groups.setdefault(key, []).append(rec)
    print(f"\n{'class':<32} {'n':>3} {'no ref':>6} {'within':>6} {'pass':>6} {'laser':>6} {'on axis µm':>10} "
          f"{'offset µm':>10} {'ratio':>6} {'worst':>6} {'uncomp. µm':>10}   (rates over the scenarios judged; "
          f"medians; laser: passes but for what the on-axis run adds too)")
    for key in sorted(groups, key=lambda k: (k != "all", k.count(" "), k)):
        items = groups[key]
        judged = [v for v in items if v.get("judged") != NO_REFERENCE]
        rate = lambda f: f"{np.mean([f(v) for v in judged]):.0%}" if judged else "-"  # noqa: E731
        med = lambda f: float(np.median([f(v) for v in judged])) if judged else np.nan  # noqa: E731
        print(f"{key:<32} {len(items):>3} {len(items) - len(judged):>6} {rate(lambda v: v['ratio'] <= RATIO_LIMIT):>6} "
              f"{rate(lambda v: v['pass']):>6} {rate(lambda v: v['pass_laser']):>6} "
              f"{med(lambda v: v['axis']['held_out_um']):>10.3f} {med(lambda v: v['offset']['held_out_um']):>10.3f} "
              f"{med(lambda v: v['ratio']):>6.2f} {max((v['ratio'] for v in judged), default=np.nan):>6.2f} "
              f"{float(np.median([v['uncompensated_um'] for v in items])):>10.1f}")
    unjudged = [v for v in records if v.get("judged") == NO_REFERENCE]
    failed = [v for v in records if not v["pass"] and v not in unjudged]
    print(f"\nfailures: {len(failed)} of {len(records) - len(unjudged)} judged")
    for rec in failed:
        _details(rec)
    print(f"\nno reference (the on-axis run refused; judged neither within nor beyond): {len(unjudged)}")
    for rec in unjudged:
        _details(rec)


def _details(rec) -> None:
    print("  " + line(rec))
    print(f"    offset {rec['laser_offset_mm']} mm; board pose (offset run): {rec['offset']['board_pose']}; "
          f"spurious {rec['offset']['spurious'] or 'none'} (on axis {rec['axis']['spurious'] or 'none'})"
          + "".join(f"; {case} refused: {rec[case]['refused']}" for case in ("axis", "offset") if "refused" in rec[case]))


def _write_json(path, records) -> None:
    """The records so far, written whole (to a temporary file, then renamed)."""
    tmp = Path(f"{path}.partial")
    tmp.write_text(json.dumps({"scenarios": records}, indent=1, default=str))
    tmp.replace(path)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", type=int, default=12)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--layouts", nargs="+", choices=LAYOUTS, default=list(LAYOUTS))
    ap.add_argument("--lens", nargs="+", choices=LENSES, default=list(LENSES))
    ap.add_argument("--jobs", type=int, default=1, help="scenarios run at once (processes)")
    ap.add_argument("--json", help="write every scenario's record here")
    ap.add_argument("--only", nargs="+", type=int, metavar="ID",
                    help="run only these scenarios (the seed printed first on a line), drawn with --layouts and --lens")
    ap.add_argument("--keep", help="with --only: leave each run's files (images, logs, fits) in DIR/ID")
    args = ap.parse_args(argv)
    if args.keep and not args.only:
        ap.error("--keep needs --only")
    seeds = args.only or [args.seed * 100003 + k for k in range(args.scenarios)]
    keeps = [str(Path(args.keep) / str(s)) if args.keep else None for s in seeds]
    started, records = time.perf_counter(), []
    with ProcessPoolExecutor(args.jobs) if args.jobs > 1 else contextlib.nullcontext() as pool:
        results = (pool.map(run, seeds, [args.layouts] * len(seeds), [args.lens] * len(seeds), keeps) if pool
                   else (run(s, args.layouts, args.lens, k) for s, k in zip(seeds, keeps)))
        for rec in results:
            records.append(rec)
            print(line(rec), flush=True)
            if args.json:
                _write_json(args.json, records)
    print(f"\n{len(records)} scenarios in {time.perf_counter() - started:.0f} s "
          f"({f'only {args.only}' if args.only else f'seed {args.seed}'})")
    summarise(records)


if __name__ == "__main__":
    main()
