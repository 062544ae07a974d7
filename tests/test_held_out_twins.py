"""The held-out check on a B head: a true tilt scale refused because of its twins, and because the check's turns
fitted a parameter the fit on all the data holds (identification/diagnosis/twins.py, fitting/crossval.py).

Truth in plain numpy: the closed loop's machine and draws (benchmarks/proving_loop.py, benchmarks/proving_truth.py,
no kinid code), the first plan `kinid plan` makes for the default model, a tilt scale of 50–150 µrad/rad (3–6 µm
at the tool) among the hidden errors; the held-out 2·RMS over 300 poses of the volume.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import norm

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
import proving_loop  # noqa: E402

from kinid.identification.diagnosis.selection import forward_select, what_is_left  # noqa: E402
from kinid.identification.diagnosis.twins import family_bar_se  # noqa: E402
from kinid.identification.fitting import cross_validate, fit  # noqa: E402
from kinid.identification.model.effects import default_model, parse_effect  # noqa: E402

TILT_SCALE = ("EBB:poly1", "EXB:poly1")  # the B scale and X moving with B move a B head's tool point alike


@pytest.fixture(scope="module")
def bhead():
    """(machine, truth, layout, the first plan's alignments) of the B head + C table."""
    from kinid.identification.planning.plan import plan_measurement

    layout = proving_loop.LAYOUTS["five_axis_bhead_c"]
    with tempfile.TemporaryDirectory() as folder:
        machine, tm = proving_loop.load(layout, Path(folder))
    # the loop's scenarios as recorded: its first plan without drift checks (tests/test_drift_checks.py has them)
    first = plan_measurement(machine, proving_loop.candidates(machine, layout), target_um=proving_loop.TARGET_UM,
                             drift_checks=0)
    return machine, tm, layout, first.obs


def _scenario(bhead, k):
    """Scenario ``k`` of the loop's seed 1: (its first alignments, the held-out 2·RMS of a fit over the volume)."""
    machine, tm, layout, plan = bhead
    rng = np.random.default_rng([1, k])
    fixed, hidden = proving_loop.draw(layout, tm, rng)
    vol = proving_loop.volume(machine, 300, rng, layout)
    obs = proving_loop.measure(machine, tm, plan, layout, fixed, hidden, rng)
    assert "tilt scale" in [h for h, _, _ in hidden]
    return obs, lambda result: proving_loop.held_out_2rms_um(machine, tm, result, vol, layout, fixed, hidden)


@pytest.mark.parametrize("k, default_um", [(3, 4.0), (9, 3.3)])
def test_the_tilt_scale_is_added_on_the_first_alignments(bhead, k, default_um):
    """Scenario 3: the best candidate by a hair is a Z scale nearly aliased with the model (χ² drop 976.9 against
    the B scale's 976.6) that predicts no held-out block; scenario 9: the B scale itself, p = 4e-83, whose turns
    fitted a Z squareness the fit holds. Before, the first fit added nothing (held-out 4.0 and 3.3 µm); the tilt
    scale or its twin is added and the held-out error falls below a fifth of the default model's."""
    obs, held_out = _scenario(bhead, k)
    machine = bhead[0]
    steps = forward_select(machine, obs, default_model(machine))
    assert held_out(steps[0].fit) == pytest.approx(default_um, abs=0.05)
    added = [s.added for s in steps[1:]]
    assert set(added) & set(TILT_SCALE), added
    assert held_out(steps[-1].fit) < 0.2 * default_um


def test_twins_that_predict_alike_are_named_not_chosen(bhead):
    """Scenario 3's words name the member added, the twin the data cannot tell from it, and those that fit as well
    but do not predict held-out alignments."""
    obs, _ = _scenario(bhead, 3)
    machine = bhead[0]
    steps = forward_select(machine, obs, default_model(machine))
    family = next(s.family for s in steps if s.family is not None)
    assert family.best == "EZZ:poly1" and family.added in TILT_SCALE
    assert set(TILT_SCALE) - {family.added} <= set(family.alike)
    assert family.held_out.improves and family.held_out.gain_se >= family.bar_se
    words = what_is_left(steps)
    assert f"{family.added} was added of candidates that fit the data within chance of each other" in words
    assert "EZZ:poly1" in words and "kinid plan --detect" in words


def test_a_turn_holds_what_the_fit_on_all_the_data_holds(bhead):
    """Scenario 9: the fit of the default model holds a Z squareness that is identifiable at its solution. Told what
    the fit identified, the check's turns hold it too: the default model then predicts the held-out blocks no better
    than it fits all the data, and the B scale gains well over the bar; not told, the turns fit it, predict better
    than the fit on all the data and leave the B scale below the bar (the check before)."""
    obs, _ = _scenario(bhead, 9)
    machine = bhead[0]
    model = default_model(machine)
    result = fit(machine, obs, model)
    assert not result.identifiable.all()
    scale = parse_effect("EBB:poly1", machine)
    told = cross_validate(machine, obs, model, scale, theta0=result.theta, identifiable0=result.identifiable)
    assert told.rms_without_um >= result.rms_um and told.improves and told.gain_se > 10.0
    assert cross_validate(machine, obs, model, scale).gain_se == pytest.approx(told.gain_se)  # the fit made there
    untold = cross_validate(machine, obs, model, scale, theta0=result.theta)
    assert untold.rms_without_um < 0.6 * result.rms_um and not untold.improves


def test_the_family_bar_shares_the_tail_among_the_members():
    """family_bar_se against scipy's normal quantile: one member keeps MIN_GAIN_SE, m members share its tail."""
    for m in (1, 2, 6, 7):
        assert family_bar_se(m, 2.0) == pytest.approx(norm.isf(norm.sf(2.0) / m), rel=1e-6)
    assert family_bar_se(1) == pytest.approx(2.0)
