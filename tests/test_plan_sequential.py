"""The sequential design (kinid plan --augment): plan for the default model, measure, let the fit find the model,
plan what to add for it, measure that, fit all. The truth is plain numpy on the URDF text
(benchmarks/proving_truth.py, no kinid code): drawn location errors and the set-up in millimetres, an X scale
error, a two-per-turn error of C and a B scale error, each a formula of the readings; 1 µm noise.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
import bench_plan  # noqa: E402
import proving_loop  # noqa: E402

from kinid.identification.model.machine import load_machine  # noqa: E402
from kinid.urdf import path  # noqa: E402

TARGET_UM = 0.5
#: The hidden position-dependent errors, as kinid names the effects that describe them.
TRUE_EFFECTS = ("EXX:poly1", "ECC:periodic:180", "EBB:poly1")


def hidden_errors(tm, obs, names, seed) -> dict:
    """Error values (µm / µrad) per row: location errors drawn from ``seed``; X scale 40 µm/m; C two per turn,
    25 µrad, a drawn phase; B scale 100 µrad/rad."""
    rng = np.random.default_rng(seed)
    n = len(obs)
    errors = {k: np.full(n, v[0]) for k, v in bench_plan.true_errors(tm, rng, 1).items()}
    x, b, c = (obs.axes[:, names.index(a)] for a in ("X", "B", "C"))
    errors["EXX"] = 40e-3 * x
    errors["ECC"] = 25.0 * np.sin(np.radians(2.0 * c) + rng.uniform(0, 2 * np.pi))
    errors["EBB"] = 100.0 * np.radians(b)
    return errors


def measured(machine, tm, obs, seed, noise_seed):
    """The tool point the true machine reaches at the planned readings, with 1 µm noise: the observations."""
    from kinid.identification.data.observations import Observations

    names = machine.axis_names
    p = bench_plan.truth.tool_point_mm(tm, {a: obs.axes[:, j] for j, a in enumerate(names)},
                                       hidden_errors(tm, obs, names, seed), len(obs))
    p = p + np.random.default_rng(noise_seed).normal(0.0, 1.0, (len(obs), 3)) * 1e-3
    return Observations(obs.marks, p, obs.axes, None, {}, tuple(range(2, len(obs) + 2)), "<simulated>")


def random_volume(machine, k, rng):
    """``k`` poses drawn over the candidates' volume: a mark anywhere on the ±40 mm square, B in ±60°, C anywhere;
    the linear axes solved at the nominal machine (the loop's proving ground draws them so)."""
    return proving_loop.volume(machine, k, rng)


def held_out_2rms_um(machine, tm, result, volume, seed) -> float:
    """2·RMS per coordinate of the tool point ``result`` predicts at the volume's poses against the noise-free truth."""
    from kinid.identification.data.observations import Observations
    from kinid.identification.fitting.residuals import design, residuals

    names = machine.axis_names
    truth = bench_plan.truth.tool_point_mm(tm, {a: volume.axes[:, j] for j, a in enumerate(names)},
                                           hidden_errors(tm, volume, names, seed), len(volume))
    vol = Observations(volume.marks, truth, volume.axes, None, {}, (), "<volume>")
    r = residuals(machine, design(machine, result.effects, vol), vol, result.theta, jacobian=False)
    return 2.0 * float(np.sqrt(np.mean(r**2)))


_concat = proving_loop._concat  # the measured and the added rows, as one run


@pytest.fixture(scope="module")
def bc():
    from kinid.identification.model.effects import default_model, parse_effect
    from kinid.identification.planning.plan import plan_measurement
    from kinid.identification.planning.pool import candidate_poses

    machine = load_machine(path("five_axis_bc"))
    pool = candidate_poses(machine, bench_plan.MARKS_MM, {"B": bench_plan.B_DEG, "C": bench_plan.C_DEG})
    # the sequential design alone, no warm-up drawn: without drift checks (tests/test_drift_checks.py)
    first = plan_measurement(machine, pool, target_um=TARGET_UM, drift_checks=0)
    told = list(default_model(machine)) + [parse_effect(e, machine) for e in TRUE_EFFECTS]
    oracle = plan_measurement(machine, pool, target_um=TARGET_UM, effects=told, drift_checks=0)
    return machine, pool, first, oracle


def test_the_whole_loop_meets_the_target_for_the_model_the_data_reveal(bc):
    """plan (0.5 µm) → measure → identify --auto → plan --augment → measure the added → identify --auto on all, over
    4 seeds: the held-out 2·RMS over random poses of the volume meets the target ×1.1 in the mean, better than the
    first fit's, and the total count is at most 1.3 × what the plan asks when told the true effects."""
    from kinid.identification.model.effects import default_model
    from kinid.identification.diagnosis.selection import forward_select
    from kinid.identification.planning.augment import augment_plan

    machine, pool, first, oracle = bc
    tm = bench_plan.truth.read_urdf(Path(machine.path).read_text())
    volume = random_volume(machine, 300, np.random.default_rng(77))
    before, after, totals, lines = [], [], [], []
    for seed in range(4):
        d1 = measured(machine, tm, first.obs, seed, 1000 + seed)
        f1 = forward_select(machine, d1, default_model(machine))[-1].fit
        aug = augment_plan(machine, d1, pool, f1.effects, noise_um=1.0, target_um=TARGET_UM)
        assert aug.plan.u_tool_um <= TARGET_UM < aug.u_measured_um, (aug.plan.u_tool_um, aug.u_measured_um)
        assert 0 < aug.plan.bound_count <= len(aug.plan.obs)
        d2 = measured(machine, tm, aug.plan.obs, seed, 2000 + seed)
        f2 = forward_select(machine, _concat(d1, d2), default_model(machine))[-1].fit
        before.append(held_out_2rms_um(machine, tm, f1, volume, seed))
        after.append(held_out_2rms_um(machine, tm, f2, volume, seed))
        totals.append(len(first.obs) + len(aug.plan.obs))
        lines.append(f"seed {seed}: first {[e.name for e in f1.effects if ':' in e.name]} {before[-1]:.3f} µm; "
                     f"+{len(aug.plan.obs)} (bound {aug.plan.bound_count}) → {[e.name for e in f2.effects if ':' in e.name]} "
                     f"{after[-1]:.3f} µm")
    print("\n".join(lines), f"\noracle plan {len(oracle.obs)}", file=sys.stderr)
    assert np.mean(after) <= 1.1 * TARGET_UM, lines
    assert np.mean(after) < np.mean(before), lines
    assert max(totals) <= 1.3 * len(oracle.obs), (totals, len(oracle.obs))


def test_nothing_is_added_when_the_measured_alignments_already_meet_the_target(bc):
    """The plan's own alignments and the default model: the plan met the target, so the design adds none; asked for
    a tighter target it adds some, and the relaxation's bound is at most what it adds."""
    from kinid.identification.model.effects import default_model
    from kinid.identification.planning.augment import augment_plan

    machine, pool, first, _ = bc
    same = augment_plan(machine, first.obs, pool, default_model(machine), noise_um=1.0, target_um=TARGET_UM)
    assert len(same.plan.obs) == 0 and same.u_measured_um == pytest.approx(first.u_tool_um, rel=1e-6)
    tighter = augment_plan(machine, first.obs, pool, default_model(machine), noise_um=1.0, target_um=0.4)
    assert tighter.plan.u_tool_um <= 0.4 and 0 < tighter.plan.bound_count <= len(tighter.plan.obs)


def test_the_added_bound_holds_for_every_addition():
    """No n candidates added to fixed rows reach φ below the bound: greedy and random additions on random problems."""
    from kinid.identification.planning.design import added_bound, criterion, select

    rng = np.random.default_rng(3)
    for trial in range(5):
        N, P = int(rng.integers(30, 90)), int(rng.integers(3, 8))
        J = rng.normal(size=(N, 3, P)) * rng.uniform(0.1, 3.0, size=P)
        Wv = rng.normal(size=(P, P))
        W = Wv @ Wv.T
        fixed = np.arange(int(rng.integers(1, 4)))
        for n in (2, 5, 10):
            bound = added_bound(J, W, fixed, n)
            greedy = select(J, W, count=len(fixed) + n, start=fixed).index
            assert list(greedy[:len(fixed)]) == list(fixed) and len(greedy) == len(fixed) + n
            for d in [greedy] + [np.r_[fixed, rng.choice(np.arange(len(fixed), N), n, replace=False)] for _ in range(20)]:
                assert criterion(J, W, d) >= bound * (1 - 1e-9), (trial, n)


def _kinid(*args, cwd):
    return subprocess.run([sys.executable, "-m", "kinid", *args], cwd=cwd, capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def measured_run(tmp_path_factory):
    """kinid plan → simulate (examples/errors_position.json) → identify --auto --target-um 0.5, as files."""
    tmp = tmp_path_factory.mktemp("sequential")
    urdf = str(path("five_axis_bc"))
    steps = [("plan", "--machine", urdf, "--target-um", "0.5", "--out", "plan.csv"),
             ("simulate", "--machine", urdf, "--errors", str(ROOT / "examples" / "errors_position.json"), "--plan",
              "plan.csv", "--noise-um", "1", "--out", "obs.csv"),
             ("identify", "--machine", urdf, "--data", "obs.csv", "--auto", "--target-um", "0.5", "--out", "fit.json")]
    outs = []
    for step in steps:
        r = _kinid(*step, cwd=tmp)
        assert r.returncode == 0, r.stderr
        outs.append(r.stdout)
    return tmp, outs[-1]


def test_identify_says_the_model_found_needs_more_and_the_command_plans_it(measured_run):
    tmp, out = measured_run
    said = [line for line in out.splitlines() if line.startswith("tool point: U")]
    assert len(said) == 1 and "above the target 0.5 µm" in said[0], out
    command = said[0].split("plan the alignments to add: ")[1]
    assert command == "kinid plan --augment fit.json --data obs.csv --target-um 0.5 --out more.csv"
    r = _kinid(*command.split()[1:], cwd=tmp)
    assert r.returncode == 0, r.stderr
    assert "added alignments written to more.csv" in r.stdout and "measured and added: U = " in r.stdout
    u = float(r.stdout.split("measured and added: U = ")[1].split()[0])
    assert u <= 0.5
    from kinid.identification.data.observations import read_observations

    added = read_observations(tmp / "more.csv", load_machine(path("five_axis_bc")), optional_axes=("X", "Y", "Z"))
    assert 0 < len(added) < len((tmp / "obs.csv").read_text().splitlines()) - 1


@pytest.mark.parametrize("change, words", [
    ("machine", "is not the machine fit.json was fitted on"),
    ("columns", "is an axis the machine of fit.json lacks"),
    ("other data", "does not describe these data"),
    ("no data", "--augment needs --data"),
])
def test_inputs_that_do_not_belong_together_are_refused(measured_run, change, words):
    tmp, _ = measured_run
    args = ["plan", "--augment", "fit.json", "--data", "obs.csv", "--target-um", "0.5", "--out", "bad.csv"]
    if change == "machine":
        args += ["--machine", str(path("five_axis_ac"))]
    elif change == "columns":
        text = (tmp / "obs.csv").read_text().splitlines()
        rows = [text[0].replace("b_deg", "b_deg,a_deg")] + [_with_a(line, text[0]) for line in text[1:]]
        (tmp / "other.csv").write_text("\n".join(rows) + "\n")
        args[4] = "other.csv"
    elif change == "other data":
        (tmp / "far.json").write_text('{"EX0C": 300.0, "EA0B": -250.0, "EC0Y": 80.0}')
        r = _kinid("simulate", "--machine", str(path("five_axis_bc")), "--errors", "far.json", "--plan", "plan.csv",
                   "--noise-um", "1", "--out", "far.csv", cwd=tmp)
        assert r.returncode == 0, r.stderr
        args[4] = "far.csv"
    else:
        del args[3:5]
    r = _kinid(*args, cwd=tmp)
    assert r.returncode == 2, r.stdout + r.stderr
    assert words in r.stderr and "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not (tmp / "bad.csv").exists()


def _with_a(line, header):
    """``line`` with a value for the a_deg column inserted after b_deg's."""
    cells = line.split(",")
    k = header.split(",").index("b_deg")
    return ",".join(cells[:k + 1] + ["0"] + cells[k + 1:])
