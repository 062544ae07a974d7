"""The patent's UVW test plan and compensation, including its worked example."""
import numpy as np
import pytest

from kinid.errors import DataError, StageError
from kinid.stages.uvw import SimulatedUVWStage, calibrate_patent, patent_compensation_um
from kinid.stages.uvw.simulate import ActuatorTruth
from kinid.stages.uvw.patent import PatentCompensator, PatentStatistics, measure_patent, patent_statistics, patent_strokes


def _worked_example_errors():
    """Fig. 6 of the patent: 18 measurements at each of 500, 1000, 1500 µm with ΔXn 2.02, ΔXm 2.62, ΔX 2.29 µm.

    The table itself is not in the text; these errors have exactly its three means (the 1000 µm value
    follows from ΔX = (ΔXn + e_1000 + ΔXm)/3).
    """
    rng = np.random.default_rng(3)
    strokes, errors = [], []
    for s, mean in ((500.0, 2.02), (1000.0, 3 * 2.29 - 2.02 - 2.62), (1500.0, 2.62)):
        e = rng.normal(0.0, 0.3, 18)
        e += mean - e.mean()
        strokes += [s] * 18
        errors += list(e)
    return np.array(strokes), np.array(errors)


def test_worked_example_reproduces_096_and_325():
    s, e = _worked_example_errors()
    m, mid, n = patent_strokes(2000.0)
    assert (m, mid, n) == (500.0, 1000.0, 1500.0)
    stats = patent_statistics(s, e, m, n)
    assert stats.at_m_um == pytest.approx(2.02, abs=1e-12)
    assert stats.at_n_um == pytest.approx(2.62, abs=1e-12)
    assert stats.mean_um == pytest.approx(2.29, abs=1e-12)
    assert stats.repeats == 18
    assert patent_compensation_um(stats, 1600.0, forward=True) == pytest.approx(0.96, abs=1e-12)
    assert patent_compensation_um(stats, 1600.0, forward=False) == pytest.approx(3.25, abs=1e-12)


def test_compensator_applies_patent_formula_with_direction():
    st = PatentStatistics(mean_um=2.29, at_m_um=2.02, at_n_um=2.62, m_um=500.0, n_um=1500.0)
    comp = PatentCompensator({"X1": st})
    # forward from home: the extra stroke is the patent's x1'
    assert comp.command("X1", 1600.0) - 1600.0 == pytest.approx(0.96, abs=1e-12)
    assert comp.state("X1")[2] == 1
    # reverse back to home: ΔX more travel in reverse (command lower by ΔX)
    assert comp.command("X1", 0.0) == pytest.approx(-2.29, abs=1e-12)
    assert comp.state("X1")[2] == -1
    # a reverse move of stroke 1600 starting at home: extra reverse stroke is the patent's x2' = 3.25
    comp.reset("X1")
    assert comp.command("X1", -1600.0) - (-1600.0) == pytest.approx(-3.25, abs=1e-12)
    with pytest.raises(StageError, match="was not calibrated"):
        comp.command("Y", 10.0)


def test_patent_test_step_on_scale_and_backlash_stage():
    """Without periodic error the patent measures slope = -scale and ΔX = backlash + slope·a (noise-free)."""
    k_ppm, b_um = -400.0, 1.8
    truth = {a: ActuatorTruth(2000.0, scale_ppm=k_ppm, backlash_um=b_um) for a in ("X1", "X2", "Y")}
    stage = SimulatedUVWStage(truth, noise_um=0.0)
    s, e = measure_patent(stage.move, "X1", 2000.0, repeats=10)
    assert len(s) == 30
    stats = patent_statistics(s, e, 500.0, 1500.0)
    assert stats.slope == pytest.approx(-k_ppm * 1e-6, abs=1e-12)
    assert stats.at_m_um == pytest.approx(b_um - k_ppm * 1e-6 * 500.0, abs=1e-9)
    assert stats.mean_um == pytest.approx(b_um - k_ppm * 1e-6 * 1000.0, abs=1e-9)
    # the patent's reverse compensation carries the scale error at mid stroke into the backlash
    assert stats.mean_um - b_um == pytest.approx(0.4, abs=1e-9)


def test_patent_slope_is_blind_to_cosine_but_hit_by_sine_lead_error():
    """Strokes 0.5a and 1.5a sit a quarter and three quarters into the lead: a cosine lead error cancels
    in ΔXm − ΔXn, a sine one of amplitude A shifts the slope by 2A/(n1 − m1)."""
    base = dict(lead_um=2000.0, scale_ppm=0.0, backlash_um=1.0)
    for per, expected_slope in ((((0.0, 0.8),), 0.0), (((0.8, 0.0),), 2 * 0.8 / 1000.0)):
        truth = {a: ActuatorTruth(periodic_um=per, **base) for a in ("X1", "X2", "Y")}
        comp = calibrate_patent(SimulatedUVWStage(truth, noise_um=0.0).move, 2000.0, repeats=10)
        assert comp.stats["Y"].slope == pytest.approx(expected_slope, abs=1e-12)


@pytest.mark.parametrize("lead", [0.0, -2000.0, float("nan"), "abc"])
def test_non_positive_lead_is_a_clear_error(lead):
    stage = SimulatedUVWStage(noise_um=0.0)
    with pytest.raises(DataError, match="lead_um must be a positive number"):
        calibrate_patent(stage.move, lead)
    with pytest.raises(DataError, match="lead_um must be a positive number"):
        patent_strokes(lead)


def test_bad_inputs():
    stage = SimulatedUVWStage(noise_um=0.0)
    with pytest.raises(StageError, match="unknown actuator 'Z'"):
        measure_patent(stage.move, "Z", 2000.0)
    with pytest.raises(DataError, match="repeats must be an integer >= 1"):
        measure_patent(stage.move, "X1", 2000.0, repeats=0)
    with pytest.raises(StageError, match="no measurement at stroke"):
        patent_statistics([1000.0], [1.0], 500.0, 1500.0)
    with pytest.raises(StageError, match="unknown actuator 'W'"):
        PatentCompensator({"W": PatentStatistics(1, 1, 1, 500, 1500)})
