"""End-to-end UVW demonstration on a simulated stage: the patent's method against the model.

:func:`run_demo` calibrates a :class:`SimulatedUVWStage` both ways, drives the
same random alignment moves (50–2000 µm) uncompensated, with the patent's
compensation and with the model's, and returns plain numbers (JSON-ready);
:func:`plot_demo` draws errors before/after and the residual against position
modulo the lead.
"""
from __future__ import annotations

import math

import numpy as np

from kinid.checks import check_int

from .calibrate import alignment_targets, calibrate, run_moves, run_stage_moves
from .kinematics import ACTUATORS, Pose, UVWGeometry, check_lead
from .model import phase_residuals
from .patent import PatentStatistics, calibrate_patent, patent_compensation_um
from .simulate import SimulatedUVWStage, default_truth

__all__ = ["run_demo", "plot_demo", "WORKED_EXAMPLE"]

#: The patent's worked example (fig. 6): µm.
WORKED_EXAMPLE = PatentStatistics(mean_um=2.29, at_m_um=2.02, at_n_um=2.62, m_um=500.0, n_um=1500.0, repeats=18)


def _stats(e):
    e = np.asarray(e, dtype=float)
    return {"max_um": float(np.abs(e).max()), "rms_um": float(np.sqrt(np.mean(e ** 2)))}


def run_demo(*, seed: int = 0, noise_um: float = 0.1, lead_um: float = 2000.0, repeats: int = 3,
             patent_repeats: int = 18, moves: int = 200, geometry=None, progress=None) -> dict:
    """Run the comparison and return its numbers.

    Parameters
    ----------
    seed : int
        Seed of the measurement noise and of the random moves.
    noise_um : float
        Vision noise of the simulated stage, µm.
    lead_um : float
        Screw lead of the simulated actuators, µm (> 0).
    repeats : int
        Bidirectional sweeps of the model's test plan.
    patent_repeats : int
        Measurements per stroke of the patent's test (10 to 30 in the patent).
    moves : int
        Validation alignment moves per actuator (and stage moves).
    geometry : UVWGeometry or None
        Stage geometry for the stage-level moves (default a = b = 50 mm).
    progress : bool or None
        Progress line during calibration.

    Returns
    -------
    dict
        ``worked_example``, ``patent`` (statistics per actuator), ``model``
        (values, std, truth per actuator), ``validation`` (max/rms error per
        actuator and method), ``stage`` (pose errors per method) and the raw
        arrays under ``_arrays`` (not JSON; dropped by the CLI).
    """
    lead = check_lead(lead_um)
    moves = check_int("moves", moves, minimum=1)
    geometry = UVWGeometry() if geometry is None else geometry
    rng = np.random.default_rng(seed)
    truth = default_truth(lead)
    travel = max(1.5 * lead, 2000.0) + 1000.0
    stage = SimulatedUVWStage(truth, noise_um=noise_um, travel_um=travel, rng=rng)
    model_comp = calibrate(stage.move, lead, repeats=repeats, noise_um=noise_um if noise_um > 0 else None,
                           progress=progress)
    model_moves = model_comp.moves
    before = stage.moves
    patent_comp = calibrate_patent(stage.move, lead, repeats=patent_repeats)
    patent_moves = stage.moves - before

    span = model_comp.models["X1"].span_um
    methods = {"uncompensated": None, "patent": patent_comp, "model": model_comp}
    validation, arrays = {}, {"targets": {}, "errors": {m: {} for m in methods}, "phase": {}}
    for name in ACTUATORS:
        targets = alignment_targets(rng, moves, low_um=span[0], high_um=span[1])
        arrays["targets"][name] = targets
        validation[name] = {}
        for label, comp in methods.items():
            err = run_moves(stage.move, name, targets, comp, truth=stage.true_um)
            arrays["errors"][label][name] = err
            validation[name][label] = _stats(err)
        arrays["phase"][name] = phase_residuals(model_comp.models[name])
    overall = {label: _stats(np.concatenate([arrays["errors"][label][n] for n in ACTUATORS])) for label in methods}

    # Stage-level alignment moves: x, y and θ together (a rotation = two X moves and one Y move).
    theta_max_deg = math.degrees(0.4 * lead / (1e3 * geometry.a_mm))
    poses, pos = [], np.zeros(3)
    for _ in range(moves):
        step = rng.uniform(-1.0, 1.0, 3) * np.array([0.5 * lead, 0.5 * lead, 0.5 * theta_max_deg])
        pos = np.clip(pos + step, [-lead, -lead, -theta_max_deg], [lead, lead, theta_max_deg])
        poses.append(Pose(float(pos[0]), float(pos[1]), float(pos[2])))
    stage_errors = {}
    for label, comp in methods.items():
        e = run_stage_moves(stage.move, geometry, poses, comp, truth=stage.true_um)
        arrays.setdefault("stage", {})[label] = e
        stage_errors[label] = {"max_x_um": float(np.abs(e[:, 0]).max()), "max_y_um": float(np.abs(e[:, 1]).max()),
                               "max_theta_urad": float(np.abs(e[:, 2]).max())}

    model_out = {}
    for name, m in model_comp.models.items():
        t = truth[name]
        true_vals = {"scale_ppm": t.scale_ppm, "backlash_um": t.backlash_um}
        for h, (s, k) in enumerate(t.periodic_um, start=1):
            true_vals[f"s{h}_um"], true_vals[f"k{h}_um"] = s, k
        for p, q in enumerate(t.poly_um, start=2):
            true_vals[f"poly{p}_um"] = q
        model_out[name] = {
            "parameters": {n: {"value": float(v), "std": float(sd), **({"truth": float(true_vals[n])}
                                                                       if n in true_vals else {})}
                           for n, v, sd in zip(m.names, m.values, m.std)},
            "degree": m.degree, "harmonics": m.harmonics,
            "rms_um": m.rms_um,
            "linear_only_rms_um": float(np.sqrt(np.mean(arrays["phase"][name][1] ** 2))),
        }
    return {
        "seed": seed, "noise_um": noise_um, "lead_um": lead, "moves_per_actuator": moves,
        "calibration_moves": {"patent": patent_moves, "model": model_moves},
        "worked_example": {"delta_xn_um": WORKED_EXAMPLE.at_m_um, "delta_xm_um": WORKED_EXAMPLE.at_n_um,
                           "delta_x_um": WORKED_EXAMPLE.mean_um, "stroke_um": 1600.0,
                           "forward_um": round(patent_compensation_um(WORKED_EXAMPLE, 1600.0, True), 9),
                           "reverse_um": round(patent_compensation_um(WORKED_EXAMPLE, 1600.0, False), 9)},
        "patent": {n: {"delta_x_um": s.mean_um, "delta_xn_um": s.at_m_um, "delta_xm_um": s.at_n_um,
                       "m_um": s.m_um, "n_um": s.n_um, "repeats": s.repeats, "slope_ppm": 1e6 * s.slope}
                   for n, s in patent_comp.stats.items()},
        "model": model_out,
        "validation": {"per_actuator": validation, "all": overall},
        "stage": stage_errors,
        "_arrays": arrays,
    }


def plot_demo(result: dict, path) -> None:
    """Write the demo figure (PNG) atomically.

    Panels: error of every validation move for the three methods; the
    residual of an offset + scale + reversal fit (what the patent's kind of
    model can represent) against position modulo the lead; the residual of
    the full model against the same.
    """
    from kinid.reports.figures import SHOWN_WIDTH_IN, legend_below, new_figure, save_figure

    arrays = result["_arrays"]
    fig = new_figure((SHOWN_WIDTH_IN, 3.6))
    axes = fig.subplots(1, 3)
    ax = axes[0]
    colours = {"uncompensated": "tab:gray", "patent": "tab:orange", "model": "tab:blue"}
    for label, per in arrays["errors"].items():
        e = np.concatenate([per[n] for n in ACTUATORS])
        ax.plot(e, ".", ms=3, color=colours[label],
                label=f"{label}: max {np.abs(e).max():.2f} µm")
    ax.axhline(0.6, color="k", lw=0.6, ls="--")
    ax.axhline(-0.6, color="k", lw=0.6, ls="--")
    ax.set_xlabel("alignment move (X1, X2, Y in turn)")
    ax.set_ylabel("position error (µm)")
    ax.set_title("Error after each 50–2000 µm move")
    for ax, idx, title in ((axes[1], 1, "Residual of scale + reversal fit"), (axes[2], 2, "Residual of full model")):
        for name in ACTUATORS:
            phase, lin, full = arrays["phase"][name]
            ax.plot(phase * result["lead_um"], (lin, full)[idx - 1], ".", ms=3, label=name,
                    color={"X1": "tab:purple", "X2": "tab:brown"}.get(name, "tab:olive"))
        ax.set_xlabel("commanded position modulo lead (µm)")
        ax.set_ylabel("residual (µm)")
        ax.set_title(title)
    axes[2].set_ylim(axes[1].get_ylim())
    fig.tight_layout()
    legend_below(fig, list(axes), columns=3)
    save_figure(fig, path)
