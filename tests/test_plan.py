"""kinid plan: the promise of a planned measurement checked by simulation on a truth that shares no code with kinid
(benchmarks/proving_truth.py), the relaxation's bound checked against designs, the order's time checked against the
axes, the pose advice checked by adding the advised poses.

The full side-by-side (kinid's choice, FIGAROH's D-optimal relaxation, random, the patent's plan; 20 seeds) is
``python benchmarks/bench_plan.py``; its table is in docs/plan.md.
"""
from __future__ import annotations

import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
import bench_plan  # noqa: E402

from kinid.identification.model.machine import load_machine  # noqa: E402
from kinid.urdf import path  # noqa: E402

B_DEG = np.arange(-60.0, 61.0, 10.0)
C_DEG = np.arange(0.0, 360.0, 15.0)


@pytest.fixture(scope="module")
def bc():
    from kinid.identification.planning.plan import plan_measurement
    from kinid.identification.planning.pool import candidate_poses

    machine = load_machine(path("five_axis_bc"))
    pool = candidate_poses(machine, bench_plan.MARKS_MM, {"B": B_DEG, "C": C_DEG})
    # the design's promise alone: the drift checks (repeats of one pose) are tested in test_drift_checks.py
    return machine, pool, plan_measurement(machine, pool, target_um=0.5, drift_checks=0)


def test_a_plan_for_half_a_micrometre_keeps_its_promise_in_simulation(bc):
    """B/C machine, 1 µm noise, target 0.5 µm (k = 2): at most 100 alignments; fitted on simulated readings (every
    location error and the mm set-up drawn, plain-numpy truth), the tool point kinid predicts at every candidate pose
    is within U in ~95 % of coordinates and its RMS is U/2 within the spread of 6 seeds."""
    machine, pool, plan = bc
    assert len(plan.obs) <= 100 and plan.u_tool_um <= 0.5
    assert plan.bound_count <= len(plan.obs)
    text = Path(machine.path).read_text()
    errs = [bench_plan.held_out(machine, text, plan.obs, pool, seed) for seed in range(6)]
    rms2 = np.array([2 * np.sqrt(np.mean(e**2)) for e in errs])
    within = np.mean(np.abs(np.concatenate([e.ravel() for e in errs])) <= plan.u_tool_um)
    assert within >= 0.92, within
    assert 0.8 * plan.u_tool_um <= rms2.mean() <= 1.2 * plan.u_tool_um, (rms2, plan.u_tool_um)


def test_the_choice_beats_random_choices_of_the_same_count(bc):
    from kinid.identification.planning.plan import tool_point_u_um, volume_weight

    _, pool, plan = bc
    J = plan.candidates.J
    W = volume_weight(J)
    rng = np.random.default_rng(5)
    rows = plan.chosen[plan.order.index]
    ours = tool_point_u_um(J, W, rows, 1.0)[0]
    randoms = [tool_point_u_um(J, W, rng.choice(len(pool), len(rows), replace=False), 1.0)[0] for _ in range(10)]
    assert ours < min(randoms), (ours, randoms)


def test_the_relaxation_bound_holds_for_every_design():
    """No design of n candidates has φ below bound/n: greedy, exchanged and random designs on random problems."""
    from kinid.identification.planning.design import criterion, relaxation_bound, select

    rng = np.random.default_rng(0)
    for trial in range(6):
        N, P = int(rng.integers(30, 120)), int(rng.integers(3, 9))
        J = rng.normal(size=(N, 3, P)) * rng.uniform(0.1, 3.0, size=P)
        Wv = rng.normal(size=(P, P))
        W = Wv @ Wv.T
        bound, w = relaxation_bound(J, W)
        assert abs(w.sum() - 1) < 1e-9 and bound > 0
        for n in (3, 6, 12):
            chosen = select(J, W, count=n).index
            assert len(set(chosen)) == n
            designs = [chosen] + [rng.choice(N, n, replace=False) for _ in range(20)]
            for d in designs:
                assert criterion(J, W, d) >= bound / n * (1 - 1e-9), (trial, n)


def test_every_layout_gets_an_order_whose_time_follows_no_axis():
    from kinid.identification.planning.plan import plan_measurement
    from kinid.identification.planning.pool import candidate_poses

    for name, ranges in (("five_axis_bc", {"B": B_DEG, "C": C_DEG}), ("five_axis_ac", {"A": B_DEG, "C": C_DEG}),
                         ("five_axis_bhead_c", {"B": B_DEG, "C": C_DEG})):
        machine = load_machine(path(name))
        pool = candidate_poses(machine, bench_plan.MARKS_MM, ranges)
        plan = plan_measurement(machine, pool, count=60)
        assert plan.order.worst_correlation <= 0.2, (name, plan.order.correlation)
        t = plan.obs.t_s
        assert np.all(np.diff(t) > 0)
        for j, a in enumerate(machine.axes):
            x = plan.obs.axes[:, j]
            if np.ptp(x) > 0:
                assert abs(np.corrcoef(t, x)[0, 1]) <= 0.2, (name, a.name)


def test_the_planned_order_keeps_a_warm_up_apart_from_the_axes(bc):
    """The same alignments in the plan's order and axis-major (B the outer loop, then C): with a warm-up during the
    run, --auto finds a time effect in the plan's order every time and predicts the cold machine well; axis-major
    mixes the warm-up into the axes' errors."""
    machine, pool, plan = bc
    names = machine.axis_names
    axis_major = bench_plan.axis_major(machine, pool, plan.chosen, ("B", "C"))
    assert abs(np.corrcoef(axis_major.t_s, axis_major.axes[:, names.index("B")])[0, 1]) > 0.9
    ours = [bench_plan.warm_up_run(machine, pool, plan.obs, seed) for seed in range(10, 15)]
    theirs = [bench_plan.warm_up_run(machine, pool, axis_major, seed) for seed in range(10, 15)]
    assert all(timed for _, timed in ours), ours
    assert max(e for e, _ in ours) < 1.0, ours
    assert np.mean([e for e, _ in ours]) < 0.6 * np.mean([e for e, _ in theirs]), (ours, theirs)


def test_an_effect_asked_for_is_detected_as_often_as_promised(bc):
    """--detect EXX:periodic:10=1 with power 0.8 on a plan of 30: the lead error (amplitude 1 µm, random phase) added
    to drawn location errors is found by the diagnosis (its F test at its Bonferroni level) at least as often as
    promised, within the spread of 30 runs (the promise is for the least detectable phase)."""
    from kinid.identification import default_model
    from kinid.identification.diagnosis.diagnose import diagnose
    from kinid.identification.data.observations import Observations
    from kinid.identification.planning.plan import plan_measurement

    machine, pool, _ = bc
    plan = plan_measurement(machine, pool, count=30, detect={"EXX:periodic:10": 1.0}, power=0.8)
    size, promised = plan.powers["EXX:periodic:10"]
    assert promised >= 0.8 and len(plan.obs) > 30
    tm = bench_plan.truth.read_urdf(Path(machine.path).read_text())
    names, o, n = machine.axis_names, plan.obs, len(plan.obs)
    hits, runs = 0, 30
    for seed in range(runs):
        rng = np.random.default_rng(seed)
        errors = {k: np.full(n, v[0]) for k, v in bench_plan.true_errors(tm, rng, 1).items()}
        errors["EXX"] = size * np.sin(2 * np.pi * o.axes[:, names.index("X")] / 10.0 + rng.uniform(0, 2 * np.pi))
        p = bench_plan.truth.tool_point_mm(tm, {a: o.axes[:, j] for j, a in enumerate(names)}, errors, n)
        data = Observations(o.marks, p + rng.normal(0.0, 1.0, (n, 3)) * 1e-3, o.axes, o.t_s, {},
                            tuple(range(2, n + 2)), "<simulated>")
        d = diagnose(machine, data, default_model(machine), noise_um=1.0)
        found = [c for c in d.live if c.effect.startswith("EXX:periodic:10")]
        hits += bool(found) and found[0].p_value < 0.01 / max(len(d.live), 1)
    assert hits / runs >= promised - 2 * np.sqrt(promised * (1 - promised) / runs), (hits, promised)


def _identifiable_after(machine, effects, obs, advice):
    from kinid.identification.fitting.identifiability import analyse
    from kinid.identification.fitting.residuals import design, residuals

    both = [obs, advice.poses]
    J = []
    for o in both:
        o = replace(o, t_s=None)
        d = design(machine, effects, o)
        J.append(residuals(machine, d, o, np.zeros(d.n_params))[1].reshape(-1, d.n_params))
    names = design(machine, effects, obs).param_names()
    before = analyse(J[0], names).identifiable[names.index(advice.name)]
    after = analyse(np.vstack(J), names).identifiable[names.index(advice.name)]
    return before, after


@pytest.mark.parametrize("case", ["five_axis_bc", "arm"])
def test_adding_the_advised_poses_determines_the_held_parameters(case, tmp_path):
    """Candidates that leave parameters undetermined (B/C: the tilt axis at 0° only; the arm: its last joint at 0°):
    the advice names poses for them, and with those poses added each named parameter is identifiable."""
    from kinid.identification.model.effects import default_model
    from kinid.identification.model.machine import machine_from_urdf
    from kinid.identification.planning.plan import plan_measurement
    from kinid.identification.planning.pool import candidate_poses
    from kinid.identification.planning.advice import advice_pool

    if case == "arm":
        from kinid.identification.model.urdf_import import identification_urdf

        text = identification_urdf((ROOT / "examples" / "ur_like.urdf").read_text(), base="world",
                                   tool="wrist_3_link", tool_offset_m=(0.01, -0.02, 0.08))
        machine = machine_from_urdf(text, "ur_like_kinid.urdf")
        ranges = {"J1": (-90, 90), "J2": (-150, -30), "J3": (30, 150), "J4": (-180, 0), "J5": (60, 120), "J6": (0, 0)}
        pool = candidate_poses(machine, np.zeros((1, 3)), ranges, samples=800, rng=np.random.default_rng(1))
    else:
        machine = load_machine(path(case))
        pool = candidate_poses(machine, bench_plan.MARKS_MM, {"B": [0.0], "C": np.arange(0.0, 360.0, 30.0)})
    wide = advice_pool(machine, bench_plan.MARKS_MM, samples=800, rng=np.random.default_rng(2))
    plan = plan_measurement(machine, pool, count=40, advice_pool=wide)
    advised = [a for a in plan.advice if a.poses is not None]
    assert len(advised) >= 3, [a.name for a in plan.advice]
    for a in advised:
        assert len(a.poses) <= 6 and a.seconds > 0
        before, after = _identifiable_after(machine, default_model(machine), plan.obs, a)
        assert not before and after, a.name


def _kinid(*args, cwd):
    return subprocess.run([sys.executable, "-m", "kinid", *args], cwd=cwd, capture_output=True, text=True, timeout=300)


def test_the_plan_file_is_what_simulate_and_identify_read(tmp_path):
    """kinid plan -> simulate --plan -> identify: the fit of the planned alignments reaches the promise's scale."""
    urdf = str(path("five_axis_bc"))
    r = _kinid("plan", "--machine", urdf, "--target-um", "0.8", "--out", "plan.csv", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "plan written to plan.csv" in r.stdout and "machine time" in r.stdout
    r = _kinid("plan", "--machine", urdf, "--target-um", "0.8", "--json", "--out", "plan2.csv", cwd=tmp_path)
    import json

    summary = json.loads(r.stdout)
    assert summary["tool_point_U_k2_um"] <= 0.8 and summary["alignments"] == len(
        (tmp_path / "plan2.csv").read_text().splitlines()) - 1
    (tmp_path / "errors.json").write_text('{"EX0C": 12.0, "EA0B": -25.0, "EC0Y": 8.0, "EX0W": 1.5}')
    r = _kinid("simulate", "--machine", urdf, "--errors", "errors.json", "--plan", "plan.csv", "--noise-um", "1",
               "--out", "obs.csv", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    r = _kinid("identify", "--machine", urdf, "--data", "obs.csv", "--noise-um", "1", "--out", "fit.json", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    from kinid.identification.fitting.fit_file import load_fit

    fit = load_fit(tmp_path / "fit.json")
    k = fit.param_names.index("EX0C")
    assert abs(fit.values[k] - 12.0) < 4 * fit.std[k]


@pytest.mark.parametrize("args, words", [
    (["--range", "B=60:-60:10"], "START ≤ STOP"),
    (["--range", "Q=0:1:1"], "AXIS one of"),
    (["--target-um", "-1"], "positive"),
    (["--count", "5", "--target-um", "1"], "choose one"),
    (["--target-um", "0.0001", "--range", "B=0", "--range", "C=0:90:90"], "out of reach"),
    (["--add", "EXX:drift", "--count", "20"], "depend on time"),
    (["--detect", "EXX:periodic:10", "--count", "20"], "NAME=U"),
])
def test_bad_plan_input_is_one_line_and_exit_2(tmp_path, args, words):
    r = _kinid("plan", "--machine", str(path("five_axis_bc")), "--out", "p.csv", *args, cwd=tmp_path)
    assert r.returncode == 2, r.stdout + r.stderr
    assert words in r.stderr and "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "p.csv").exists()
