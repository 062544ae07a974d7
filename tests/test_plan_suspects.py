"""Suspects: effects the data hint at without establishing them, and the alignments `plan --augment` adds to settle
them (identification/planning/suspects.py). The truth is plain numpy: a linear model's F test simulated, and the
closed loop of benchmarks/proving_loop.py (benchmarks/proving_truth.py, no kinid code) on a B/C machine.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
import proving_loop  # noqa: E402

from kinid.identification.planning.suspects import suspect_power, estimated_columns  # noqa: E402


def _f_test_rate(X, Z, c, alpha, draws, rng) -> float:
    """How often the F test of ``Z``'s columns beside ``X``'s rejects at ``alpha`` when y = X·1 + Z·c + N(0, 1), σ
    estimated from the residuals: plain numpy least squares and scipy's F quantile."""
    from scipy.stats import f as f_dist

    n, p, k = X.shape[0], X.shape[1], Z.shape[1]
    dof = n - p - k
    Y = (X.sum(axis=1) + Z @ c)[:, None] + rng.normal(0.0, 1.0, (n, draws))  # one column per draw
    Q_small, Q_big = np.linalg.qr(X)[0], np.linalg.qr(np.hstack([X, Z]))[0]
    rss_small = np.sum((Y - Q_small @ (Q_small.T @ Y)) ** 2, axis=0)
    rss_big = np.sum((Y - Q_big @ (Q_big.T @ Y)) ** 2, axis=0)
    F = ((rss_small - rss_big) / k) / (rss_big / dof)
    return float(np.mean(F > f_dist.ppf(1.0 - alpha, k, dof)))


def test_the_power_promised_is_the_rate_the_test_detects_at():
    """suspect_power against the simulated F test: 60 rows of 3 coordinates, a model of 5 parameters, an effect of 2
    whose estimated coefficients are given, α = 1e-3; the promise is the rate of 2000 draws within three binomial
    standard deviations."""
    rng = np.random.default_rng(3)
    J = rng.normal(0.0, 1.0, (60, 3, 5))
    Je = rng.normal(0.0, 1.0, (60, 3, 2)) + 0.5 * J[:, :, :2]  # correlated with the model, as an effect is
    c = np.array([0.3, -0.2])
    promised = suspect_power(J, Je, c, 1e-3)
    rate = _f_test_rate(J.reshape(-1, 5), Je.reshape(-1, 2), c, 1e-3, 2000, rng)
    assert 0.2 < promised < 0.95, promised  # a case where the figure matters
    assert abs(rate - promised) < 3.0 * np.sqrt(promised * (1 - promised) / 2000) + 0.01, (rate, promised)


def test_a_parameter_the_model_holds_is_moved_into_the_model():
    """An effect whose first column lies in the model's span (the diagnosis held it at zero, its standard deviation
    0): estimated_columns leaves it out, and the power is that of the other column beside the model and it."""
    rng = np.random.default_rng(4)
    J = rng.normal(0.0, 1.0, (40, 3, 4))
    Je = np.concatenate([J[:, :, :1] * 2.0, rng.normal(0.0, 1.0, (40, 3, 1))], axis=2)
    tested = estimated_columns(Je, (1e-19, 0.05))
    assert tested.tolist() == [False, True]
    held = np.concatenate([J, Je[:, :, ~tested]], axis=2)
    rate = _f_test_rate(J.reshape(-1, 4), Je[:, :, tested].reshape(-1, 1), np.array([0.25]), 1e-3, 2000, rng)
    promised = suspect_power(held, Je[:, :, tested], np.array([0.25]), 1e-3)
    assert abs(rate - promised) < 3.0 * np.sqrt(promised * (1 - promised) / 2000) + 0.01, (rate, promised)


@pytest.fixture(scope="module")
def bc():
    from kinid.identification.planning.plan import plan_measurement

    layout = proving_loop.LAYOUTS["five_axis_bc"]
    machine, tm = proving_loop.load(layout, ROOT)
    pool = proving_loop.candidates(machine, layout)
    # the loop's scenario as recorded: its first plan without drift checks (tests/test_drift_checks.py has them)
    return layout, machine, tm, pool, plan_measurement(machine, pool, target_um=proving_loop.TARGET_UM, drift_checks=0)


def test_what_the_first_fit_only_hints_at_is_planned_for_and_found(bc):
    """The loop's B/C scenario 15 of seed 1 (a Y straightness along X of 3.9 µm and a curvature of B of 29 µrad at
    ±60°, plain-numpy truth): the first fit on the plan's 84 alignments adds nothing (held-out 2·RMS 0.86 µm against
    the target 0.5) while its best candidates come within 10× the threshold. plan --augment with them as suspects
    adds alignments that detect each at its estimated size with probability ≥ SUSPECT_POWER (without them it
    added none);
    the fit of all adds the curvature of B and meets the target, in no more than 1.3× the alignments the plan asks
    when told the true effects."""
    from kinid.identification.diagnosis.selection import forward_select
    from kinid.identification.model.effects import default_model, parse_effect
    from kinid.identification.planning.augment import augment_plan
    from kinid.identification.planning.plan import plan_measurement
    from kinid.identification.planning.suspects import SUSPECT_POWER, suspects_of

    layout, machine, tm, pool, first = bc
    rng = np.random.default_rng([1, 15])
    fixed, hidden = proving_loop.draw(layout, tm, rng)
    vol = proving_loop.volume(machine, 300, rng, layout)
    d1 = proving_loop.measure(machine, tm, first.obs, layout, fixed, hidden, rng)
    last = forward_select(machine, d1, default_model(machine))[-1]
    assert [e.name for e in last.fit.effects if ":" in e.name] == []
    before = proving_loop.held_out_2rms_um(machine, tm, last.fit, vol, layout, fixed, hidden)
    assert before > 1.1 * proving_loop.TARGET_UM
    plain = augment_plan(machine, d1, pool, last.fit.effects, noise_um=1.0, target_um=proving_loop.TARGET_UM)
    assert len(plain.plan.obs) == 0  # the target holds for the model found: nothing to plan for without suspects
    hints = suspects_of(last.diagnosis, last.fit.effects)
    assert hints and all(h.p_value <= 10 * h.threshold for h in hints)
    aug = augment_plan(machine, d1, pool, last.fit.effects, noise_um=1.0, target_um=proving_loop.TARGET_UM,
                       suspects=hints)
    assert len(aug.plan.obs) > 0
    assert all(p >= SUSPECT_POWER for _, p in aug.plan.powers.values()), aug.plan.powers
    both = proving_loop._concat(d1, proving_loop.measure(machine, tm, aug.plan.obs, layout, fixed, hidden, rng))
    f2 = forward_select(machine, both, default_model(machine))[-1].fit
    after = proving_loop.held_out_2rms_um(machine, tm, f2, vol, layout, fixed, hidden)
    told = list(default_model(machine)) + [parse_effect(layout.hidden[h].effect, machine) for h, _, _ in hidden]
    oracle = plan_measurement(machine, pool, target_um=proving_loop.TARGET_UM, effects=told, drift_checks=0)
    assert after <= 1.1 * proving_loop.TARGET_UM, (before, after, [e.name for e in f2.effects if ":" in e.name])
    assert len(first.obs) + len(aug.plan.obs) <= 1.3 * len(oracle.obs)


def test_identify_names_the_suspects_and_plan_augment_plans_for_them(bc, tmp_path):
    """The same scenario as files: identify --auto --target-um 0.5 says its U is within the target but the data hint
    at effects the model lacks, and gives the --augment command; that command names each suspect with the power the
    measured and added alignments detect it with (≥ SUSPECT_POWER), plans for the model with them and writes the
    added."""
    import subprocess

    from kinid.identification.data.observations import write_observations
    from kinid.identification.planning.suspects import SUSPECT_POWER

    layout, machine, tm, pool, first = bc
    rng = np.random.default_rng([1, 15])
    fixed, hidden = proving_loop.draw(layout, tm, rng)
    proving_loop.volume(machine, 300, rng, layout)  # (the draws of the scenario, in their order)
    write_observations(tmp_path / "obs.csv", proving_loop.measure(machine, tm, first.obs, layout, fixed, hidden, rng),
                       machine)

    def kinid(*args):
        return subprocess.run([sys.executable, "-m", "kinid", *args], cwd=tmp_path, capture_output=True, text=True,
                              timeout=300)

    r = kinid("identify", "--machine", machine.path, "--data", "obs.csv", "--auto", "--target-um", "0.5", "--out",
              "fit.json")
    assert r.returncode == 0, r.stderr
    said = [line for line in r.stdout.splitlines() if line.startswith("tool point: U")]
    assert len(said) == 1 and "but the data hint at " in said[0] and "which this model lacks" in said[0], r.stdout
    command = said[0].split("plan the alignments to add and settle what the data hint at: ")[1]
    assert command == "kinid plan --augment fit.json --data obs.csv --target-um 0.5 --out more.csv"
    r = kinid(*command.split()[1:])
    assert r.returncode == 0, r.stderr
    suspected = [line for line in r.stdout.splitlines() if line.startswith("  suspected: ")]
    assert suspected, r.stdout
    powers = [float(line.rsplit("probability ", 1)[1]) for line in suspected]
    assert all(p >= SUSPECT_POWER for p in powers), r.stdout
    assert "added alignments written to more.csv" in r.stdout and (tmp_path / "more.csv").exists()


def test_an_effect_the_model_absorbs_is_detected_at_the_level_only():
    """An effect whose column is a model column (the model absorbs it whole): its test rejects at the rate α only,
    whatever its size — the power is α, not 1 (a pseudo-inverse of the singular information said 1)."""
    rng = np.random.default_rng(5)
    J = rng.normal(0.0, 1.0, (30, 3, 4))
    assert suspect_power(J, 3.0 * J[:, :, 1:2], np.array([10.0]), 1e-3) == pytest.approx(1e-3)


def test_a_suspect_that_would_cost_more_than_its_share_is_not_planned_for():
    """Two suspects over 600 candidate rows: one the rows see clearly (a few added reach 0.8), one they barely
    separate from the model (dozens needed). With ``each_at_most`` below what the faint one needs alone, only the
    clear one is planned for; without it, the faint one takes the rows it needs."""
    from kinid.identification.planning.suspects import add_until_detected

    rng = np.random.default_rng(3)
    J = rng.normal(0.0, 1.0, (600, 3, 2))
    clear = (J, rng.normal(0.0, 3.0, (600, 3, 1)), np.array([1.0]), 1e-3)
    faint = (J, rng.normal(0.0, 0.1, (600, 3, 1)), np.array([1.0]), 1e-3)
    start = np.arange(5)
    free, p_free = add_until_detected(start, {"clear": clear, "faint": faint}, 0.8, 600)
    capped, p_capped = add_until_detected(start, {"clear": clear, "faint": faint}, 0.8, 600, each_at_most=20)
    assert len(free) - 5 > 20 and p_free["faint"] >= 0.8 and p_free["clear"] >= 0.8
    assert p_capped["clear"] >= 0.8 and p_capped["faint"] < 0.8 and len(capped) - 5 <= 20
