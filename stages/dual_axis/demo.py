"""The dual-axis story on a simulated gantry (``kinid dual-axis --simulate``): pixel-to-mm from head
moves, the patent's calibration rounds, the smooth model, both checked on held-out camera positions
against the measurement and the simulated truth; plain numbers, JSON-ready."""
from __future__ import annotations

import numpy as np

from kinid.errors import DataError

__all__ = ["run_simulation"]


def _stats(err_um: np.ndarray) -> dict:
    err = np.asarray(err_um, float).reshape(-1, 2)
    return {"max_x_um": float(np.max(np.abs(err[:, 0]))), "max_y_um": float(np.max(np.abs(err[:, 1]))),
            "max_um": float(np.max(np.hypot(err[:, 0], err[:, 1]))),
            "rms_um": float(np.sqrt(np.mean(np.sum(err ** 2, axis=1))))}


def run_simulation(*, y_start_mm=0.0, step_mm=10.0, n_steps=30, spec_um=1.0, max_rounds=5, degree=3, seed=0,
                   random_errors=False, noise_sigma=1.5, repeat_um=0.0):
    """Run the whole story on a simulated gantry.

    Parameters
    ----------
    y_start_mm, step_mm, n_steps, spec_um, max_rounds
        As in :func:`stages.dual_axis.calibrate`.
    degree : int
        Degree of the smooth model.
    seed : int
        Seed of ``np.random.default_rng`` for the simulation.
    random_errors : bool
        Use :func:`random_error_profiles` instead of the built-in error set.
    noise_sigma : float
        Image noise, grey levels.
    repeat_um : float
        Positioning repeatability of every axis, µm.

    Returns
    -------
    dict
        ``gantry``, ``pixel_to_mm``, ``table``, ``smooth``, ``held_out_mm`` and
        the summary ``report`` (JSON-ready).
    """
    from .calibrate import calibrate, check_plan, measure_pixel_to_mm, verify
    from .simulate import SimulatedGantry, random_error_profiles
    from .smooth import fit_smooth

    for name, v in (("noise_sigma", noise_sigma), ("repeat_um", repeat_um)):
        if not np.isfinite(v) or v < 0:
            raise DataError(f"must be a non-negative number, got {v!r}", parameter=name)
    if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)) or degree < 1:
        raise DataError(f"degree must be an integer >= 1, got {degree!r}")
    # validate the plan before any move (the pixel_to_mm argument is measured later)
    check_plan(y_start_mm, (0.0, y_start_mm), step_mm, n_steps, np.eye(2), spec_um, max_rounds)
    rng = np.random.default_rng(seed)
    errors = random_error_profiles(rng) if random_errors else None
    g = SimulatedGantry(errors, noise_sigma=noise_sigma, repeat_um=repeat_um, rng=rng)
    head0 = (0.0, float(y_start_mm))  # Y = V, X = 0: the plate is centred under the camera
    mr = measure_pixel_to_mm(g, y_start_mm, head0)
    from kinid.progress import Progress

    with Progress(None, "dual-axis images") as progress:
        table = calibrate(g, y_start_mm, head0, step_mm, n_steps, mr.matrix, spec_um, max_rounds=max_rounds,
                          progress=progress)
    smooth = fit_smooth(table, degree)
    held = table.y_mm[:-1] + 0.5 * float(step_mm)
    y0 = float(y_start_mm)

    def truth(comp):
        return g.compensated_offsets_um(y0, head0, held, comp)

    measured = {"table": verify(g, table, y0, head0, held, mr.matrix),
                "smooth": verify(g, smooth, y0, head0, held, mr.matrix)}
    true = {"uncompensated": truth(None), "table": truth(table), "smooth": truth(smooth)}
    better = "table" if _stats(true["table"])["max_um"] <= _stats(true["smooth"])["max_um"] else "smooth"
    report = {
        "y_start_mm": y0, "step_mm": float(step_mm), "steps": int(n_steps), "spec_um": float(spec_um),
        "pixel_to_mm": mr.matrix.tolist(), "true_pixel_to_mm": g.true_pixel_to_mm.tolist(),
        "rounds": table.rounds, "converged": table.converged,
        "max_change_um": [r.max_change_um for r in table.history],
        "smooth": {"degree": smooth.degree, "parallelism_urad": smooth.parallelism_urad,
                   "scale_um_per_m": smooth.scale_um_per_m, "fit_rms_um": smooth.rms_um.tolist()},
        "held_out": {
            "positions": len(held),
            "uncompensated_truth": _stats(true["uncompensated"]),
            "table_measured": _stats(measured["table"]), "table_truth": _stats(true["table"]),
            "smooth_measured": _stats(measured["smooth"]), "smooth_truth": _stats(true["smooth"]),
        },
        "better": better,
        "table": table.to_dict(),
    }
    return {"gantry": g, "pixel_to_mm": mr.matrix, "table": table, "smooth": smooth, "held_out_mm": held,
            "truth_um": true, "measured_um": measured, "report": report}
