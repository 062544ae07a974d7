"""An error of one rotary axis that follows another rotary axis's angle (basis ``on:<axis>``), found by ``--auto``.

The truth is put into the data by plain Pinocchio (tests/plain_machine.py, no kinid code): the shipped A/C
machine with its location errors and the C table's tilt EA0C = c + 30 µrad·sin A (a bearing sagging with the
trunnion), the readings of X, Y, Z that bring the tool point onto each mark solved by Newton, plus 1 µm noise.
"""
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from kinid.errors import DataError
from kinid.identification import forward_select, load_machine
from kinid.identification.diagnosis.selection import what_is_left
from kinid.identification.fitting.alignment import solve_axes
from kinid.identification.fitting.simulate import patent_plan
from kinid.identification.model.effects import basis_values, candidate_library, default_model, parse_effect
from kinid.urdf import path

sys.path.insert(0, str(Path(__file__).parent))
from plain_machine import PlainMachine  # noqa: E402

SAG_URAD = 30.0
NOISE_UM = 1.0


class SaggingTable(PlainMachine):
    """Location errors constant, the table's tilt about X growing with sin A."""

    def __init__(self, urdf, constants):
        super().__init__(urdf=urdf)
        self.constants = constants

    def joint_values(self, readings, directions):
        values = {code: v * 1e-6 for code, v in self.constants.items()}  # µm -> m, µrad -> rad
        values["EA0C"] = values.get("EA0C", 0.0) + SAG_URAD * 1e-6 * np.sin(np.radians(readings["A"]))
        return values


@pytest.fixture(scope="module")
def ac():
    return load_machine(path("five_axis_ac"))


def _truth(machine, seed):
    rng = np.random.default_rng(seed)
    constants = {e.code: float(rng.normal(0, 15.0)) for e in default_model(machine)}
    constants.update({"EX0W": 600.0, "EY0W": -400.0, "EC0W": 5000.0})
    return SaggingTable(str(path("five_axis_ac")), constants)


def _measured(machine, truth, plan, rng, noise_um=NOISE_UM):
    """The plan's readings of X, Y, Z at which the true machine shows each mark, with ``noise_um`` of noise."""
    names = machine.axis_names
    axes = plan.axes.copy()
    start = None
    for i, mark in enumerate(plan.w_mm):
        fixed = {a: axes[i, k] for k, a in enumerate(names) if a not in "XYZ"}
        r = truth.solve(np.asarray(mark, float), fixed, start=start)
        start = [r["X"], r["Y"], r["Z"]]
        axes[i, [names.index(a) for a in "XYZ"]] = start
    cols = [names.index(a) for a in "XYZ"]
    axes[:, cols] += rng.normal(0.0, noise_um * 1e-3, (len(axes), 3))
    return replace(plan, axes=axes, source="<plain truth>")


def _reordered(plan, order):
    """The same alignments in another order, a new run from t = 0."""
    return replace(plan, marks=tuple(plan.marks[i] for i in order), w_mm=plan.w_mm[order], axes=plan.axes[order],
                   t_s=np.sort(plan.t_s), lines=tuple(range(1, len(order) + 1)))


def _serpentine(machine, plan):
    """The order C outermost, A up and down within: time no longer follows A."""
    a, c = plan.axes[:, machine.axis_names.index("A")], plan.axes[:, machine.axis_names.index("C")]
    ci = np.unique(c, return_inverse=True)[1]
    return np.lexsort((np.where(ci % 2, -a, a), ci))


def _held_out_um(machine, effects, theta, later):
    cols = [machine.axis_names.index(a) for a in "XYZ"]
    poses = replace(later, axes=np.where(np.isin(np.arange(later.axes.shape[1]), cols), np.nan, later.axes))
    pred = solve_axes(machine, effects, theta, poses)
    return float(np.sqrt(np.mean(np.sum((pred.axes[:, cols] - later.axes[:, cols]) ** 2, axis=1)))) * 1e3


def test_the_basis_is_the_first_harmonics_of_the_other_angle(ac):
    e = parse_effect("EA0C:on:A", ac)
    assert (e.basis, e.axis, e.args, e.degree, e.n_params) == ("on", "C", ("A",), 1, 2)
    a_deg = np.array([-90.0, -30.0, 0.0, 45.0, 90.0])
    axes = np.zeros((a_deg.size, len(ac.axis_names)))
    axes[:, ac.axis_names.index("A")] = a_deg
    axes[:, ac.axis_names.index("C")] = [10.0, 200.0, -50.0, 0.0, 33.0]  # C's own angle plays no part
    a = np.radians(a_deg)
    assert np.allclose(basis_values(e, ac, axes), np.stack([np.cos(a) - 1, np.sin(a)], axis=1))
    two = parse_effect("EY0C:on:A:2", ac)
    assert np.allclose(basis_values(two, ac, axes)[:, 2:], np.stack([np.cos(2 * a) - 1, np.sin(2 * a)], axis=1))
    assert two.n_params == 4


@pytest.mark.parametrize("name, match", [("EA0C:on:X", "both be rotary"), ("EA0C:on:C", "must differ"),
                                         ("EA0C:on:Q", "not an axis"), ("EA0C:on:A:9", "order must be 1 to 4"),
                                         ("EXX:on:A", "both be rotary")])
def test_a_bad_on_effect_is_named(ac, name, match):
    with pytest.raises(DataError, match=match):
        parse_effect(name, ac)


def test_candidates_on_the_carrying_axis_read_at_three_angles(ac):
    """C's location joints on A, the trunnion that carries C; not A's on C, and none where A is read at 2 angles."""
    model = default_model(ac)
    lib = {e.name for e in candidate_library(ac, model, has_directions=False, has_time=True,
                                             positions={"X": 50, "Y": 50, "Z": 50, "A": 7, "C": 12})}
    location = {e.code for e in ac.error_joints if e.location and e.axis == "C"}
    assert {n for n in lib if ":on:" in n} == {f"{c}:on:A" for c in location}
    assert {"EA0C:on:A", "EB0C:on:A"} <= lib
    few = {e.name for e in candidate_library(ac, model, has_directions=False, has_time=True,
                                             positions={"X": 50, "Y": 50, "Z": 50, "A": 2, "C": 12})}
    assert not any(":on:" in n for n in few)


def test_no_candidates_between_a_head_and_a_table():
    """B in the tool's chain, C in the workpiece's: neither carries the other."""
    machine = load_machine(path("five_axis_bhead_c"))
    lib = candidate_library(machine, default_model(machine), has_directions=False, has_time=True)
    assert not any(e.basis == "on" for e in lib)
    assert parse_effect("EA0C:on:B", machine).n_params == 2  # still named with --add


def _selected(machine, obs):
    steps = forward_select(machine, obs, default_model(machine), noise_um=NOISE_UM)
    added = [e.name for e in steps[-1].fit.effects][len(default_model(machine)):]
    return steps, added


def _held_out(machine, obs, steps, later):
    """Held-out RMS (µm, noise-free later run) of the selected, the default and the true model fitted to ``obs``."""
    def fitted(model):
        return forward_select(machine, obs, model, noise_um=NOISE_UM, max_steps=0)[-1].fit

    models = {"auto": steps[-1].fit, "default": fitted(default_model(machine)),
              "true": fitted(default_model(machine) + [parse_effect("EA0C:on:A", machine)])}
    return {name: _held_out_um(machine, r.effects, r.theta, later) for name, r in models.items()}


@pytest.mark.slow
@pytest.mark.parametrize("seed", [7, 8])
def test_time_following_the_tilt_names_sag_and_drift_inseparable(ac, seed):
    """The patent plan (tilt outermost): time follows A, so the sag and a drift (or warm-up) of the table's tilt
    fit alike; --auto adds neither and says so, and a later run in another order is predicted as well as by the
    default model (a drift chosen silently predicted it worse)."""
    rng = np.random.default_rng(seed)
    truth = _truth(ac, seed)
    plan = patent_plan(ac)
    obs = _measured(ac, truth, plan, rng)
    steps, added = _selected(ac, obs)
    words = what_is_left(steps)
    insep = steps[-1].diagnosis.inseparable
    assert not any(":drift" in n or ":warmup" in n for n in added), added
    assert "EA0C:on:A" in insep and ("EA0C:drift" in insep or "EA0C:warmup" in insep), insep
    assert "cannot be told apart" in words and "time follows A" in words
    later = _measured(ac, truth, _reordered(plan, _serpentine(ac, plan)), rng, noise_um=0.0)
    rms = _held_out(ac, obs, steps, later)
    assert rms["auto"] <= rms["default"] * 1.02, rms


@pytest.mark.slow
@pytest.mark.parametrize("seed", [7, 8])
def test_auto_adds_the_sag_where_the_order_tells_it_from_time(ac, seed):
    """The same alignments with C outermost and A up and down within: --auto adds EA0C:on:A (no drift), and a
    later run in the patent order is predicted as well as by the true model and far better than by the default."""
    rng = np.random.default_rng(seed)
    truth = _truth(ac, seed)
    plan = patent_plan(ac)
    obs = _measured(ac, truth, _reordered(plan, _serpentine(ac, plan)), rng)
    steps, added = _selected(ac, obs)
    assert "EA0C:on:A" in added and not any(":drift" in n or ":warmup" in n for n in added), added
    theta = steps[-1].fit.theta
    k = sum(e.n_params for e in steps[-1].fit.effects[:[e.name for e in steps[-1].fit.effects].index("EA0C:on:A")])
    assert abs(theta[k + 1] - SAG_URAD) < 3.0, theta[k:k + 2]  # the sin A term, µrad
    later = _measured(ac, truth, plan, rng, noise_um=0.0)
    rms = _held_out(ac, obs, steps, later)
    assert rms["auto"] <= rms["true"] * 1.1 and rms["auto"] < 0.5 * rms["default"], rms


@pytest.mark.slow
def test_compensation_leaves_it_out_naming_the_other_axis(ac):
    """A table over C cannot hold an error that follows A: left out, named a cross compensation over A only."""
    from kinid.identification.compensation.compensate import compensation_model
    from kinid.identification.fitting.fit import fit

    rng = np.random.default_rng(5)
    obs = _measured(ac, _truth(ac, 5), patent_plan(ac), rng)
    result = fit(ac, obs, default_model(ac) + [parse_effect("EA0C:on:A", ac)], noise_um=NOISE_UM)
    left = dict(compensation_model(result).left_out)
    assert left["EA0C:on:A"].startswith("varies with A: a cross compensation"), left["EA0C:on:A"]
