"""Benchmark: an arm measured from a frame metres away and turned tens of degrees — the fit with and without the
closed-form start of the measurement frame (kinid.identification.fitting.start).

Run: ``python benchmarks/bench_arm_far_frame.py [DRAWS [POSES [SPAN_DEG]]]`` (default 60 60 120; under 0.2 s
a draw).

Truth in plain numpy (benchmarks/proving_truth.py, no kinid code): the ROS-style arm of examples/ur_like.urdf made
into an identification machine by ``kinid model``; per seeded draw the measurement frame 1-5 m from the base in
a random direction and turned 10-60° about a random axis, the measured point 10-60 mm off the flange in x and y
and along its axis (the last on EZ0J6: the same line as EZ0T, which the fit holds beside it), location errors of
100 µm / µrad (σ) on the parameters the fit identifies at the start, 60 poses with 0.05-0.3 mm of noise, 200
exact poses held out. Printed, with and without the start: the fits that converge, the draws where every
identified parameter is within 4 standard deviations of the truth, the held-out 3-D RMS (median, worst) and
the iterations. Arguments: draws, poses per draw (60), the joints' span about a random centre (±120°).

A real tracker set (the user's copy of a public UR10 laser-tracker data set, read as exported):
benchmarks/bench_tracker_ur10.py.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
import proving_truth as truth  # noqa: E402

#: Within this many standard deviations of the truth counts as recovered.
WITHIN_STD = 4.0


def arm():
    """(machine, plain-numpy truth machine, default effects, names identifiable at the start)."""
    from kinid.identification import default_model
    from kinid.identification.data.observations import Observations
    from kinid.identification.fitting.fit_pass import model_pass_qr
    from kinid.identification.fitting.identifiability import analyse
    from kinid.identification.fitting.residuals import design
    from kinid.identification.model.machine import machine_from_urdf
    from kinid.identification.model.urdf_import import identification_urdf

    text = identification_urdf((ROOT / "examples" / "ur_like.urdf").read_text(), base="world", tool="wrist_3_link")
    machine = machine_from_urdf(text, "ur_like_kinid.urdf")
    effects = list(default_model(machine))
    rng = np.random.default_rng(0)
    axes = rng.uniform(-120, 120, (60, len(machine.axes)))
    obs = Observations(tuple(f"P{i}" for i in range(60)), np.zeros((60, 3)), axes, None, {}, tuple(range(60)))
    d = design(machine, effects, obs)
    ps = model_pass_qr(machine, d, obs, np.zeros(d.n_params))
    ident = analyse(ps.R, d.param_names(), rows=ps.r.size)
    free = tuple(n for n, ok in zip(d.param_names(), ident.identifiable) if ok)
    return machine, truth.read_urdf(text), effects, free


def _rotation(axis, angle):
    a = axis / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def _xyz_angles(R):
    """Angles (a, b, c) of R = Rx(a) Ry(b) Rz(c): the set-up joints EA0W, EB0W, EC0W in their chain order."""
    return np.arctan2(-R[1, 2], R[2, 2]), np.arcsin(np.clip(R[0, 2], -1, 1)), np.arctan2(-R[0, 1], R[0, 0])


def far_errors(rng, free, distance_mm: float | None = None, turn_deg: float | None = None) -> dict:
    """The arm's errors {code: µm / µrad}: ~100 of each of ``free``'s machine terms, and the measurement frame
    ``distance_mm`` away (default: drawn over 1–5 m) turned ``turn_deg`` about a random axis (default: 10–60°)."""
    errors = {code: rng.normal(0, 100.0) for code in free if not code.endswith(("W", "T"))}
    shift = rng.normal(size=3)
    shift *= (rng.uniform(1000, 5000) if distance_mm is None else distance_mm) / np.linalg.norm(shift)
    axis = rng.normal(size=3)
    angles = _xyz_angles(_rotation(axis, np.radians(rng.uniform(10, 60) if turn_deg is None else turn_deg)))
    errors.update({f"E{d}0W": v * 1e3 for d, v in zip("XYZ", shift)})
    errors.update({f"E{d}0W": v * 1e6 for d, v in zip("ABC", angles)})
    return errors


def draw(machine, tm, free, seed, n_train=60, n_test=200, span_deg=120.0):
    """(training observations, held-out observations, truth {code: µm / µrad}, noise mm) of one seeded draw."""
    from kinid.identification.data.observations import Observations

    rng = np.random.default_rng(seed)
    errors = far_errors(rng, free)
    tool = rng.uniform(10, 60, 3) * rng.choice([-1, 1], 3)
    errors.update({"EX0T": tool[0] * 1e3, "EY0T": tool[1] * 1e3, "EZ0J6": errors.get("EZ0J6", 0.0) + tool[2] * 1e3})
    noise_mm = rng.uniform(0.05, 0.3)
    centre = rng.uniform(-120 + span_deg, 120 - span_deg, len(machine.axes)) if span_deg < 120 else np.zeros(6)

    def poses(n, sigma_mm):
        q = {a.name: c + rng.uniform(-span_deg, span_deg, n) for a, c in zip(machine.axes, centre)}
        p = truth.tool_point_mm(tm, {a.joint: q[a.name] for a in machine.axes},
                                {k: np.full(n, v) for k, v in errors.items()}, n)
        return Observations(tuple(f"P{i}" for i in range(n)), p + rng.normal(0, sigma_mm, (n, 3)),
                            np.column_stack([q[a.name] for a in machine.axes]), None, {}, tuple(range(2, n + 2)),
                            f"<draw {seed}>")

    return poses(n_train, noise_mm), poses(n_test, 0.0), errors, noise_mm


def outcome(machine, effects, train, test, errors, *, frame_start=True):
    """(fit, converged, every identified parameter within WITHIN_STD of the truth, held-out 3-D RMS mm)."""
    from kinid.identification import fit
    from kinid.identification.fitting.residuals import design, residuals

    result = fit(machine, train, effects, frame_start=frame_start)
    true = np.array([errors.get(n, 0.0) for n in result.param_names])
    ok = result.identifiable
    within = bool(np.all(np.abs(result.values[ok] - true[ok]) <= WITHIN_STD * result.std[ok]))
    held_true = bool(np.all(true[~ok] == 0.0))  # the fit holds only what the truth leaves at zero
    r = residuals(machine, design(machine, effects, test), test, result.theta, jacobian=False)
    return result, result.success, within and held_true, float(np.sqrt(np.mean(np.sum(r**2, axis=1)))) / 1e3


def main(draws: int = 60, n_train: int = 60, span_deg: float = 120.0):
    from threadpoolctl import threadpool_limits

    machine, tm, effects, free = arm()
    rows = {True: [], False: []}
    started = time.perf_counter()
    with threadpool_limits(1):
        for seed in range(draws):
            train, test, errors, _ = draw(machine, tm, free, seed, n_train=n_train, span_deg=span_deg)
            for frame_start in (True, False):
                result, *figures = outcome(machine, effects, train, test, errors, frame_start=frame_start)
                rows[frame_start].append((*figures, result.iterations))
    print(f"{draws} draws of {n_train} poses, joints within ±{span_deg:g}° of a centre, "
          f"{time.perf_counter() - started:.1f} s (both fits)")
    for frame_start, label in ((True, "closed-form start"), (False, "from zero")):
        converged = sum(r[0] for r in rows[frame_start])
        within = sum(r[0] and r[1] for r in rows[frame_start])
        held = np.array([r[2] for r in rows[frame_start]])
        iterations = np.array([r[3] for r in rows[frame_start]])
        print(f"{label:>18}: converged {converged}/{draws}, recovered within {WITHIN_STD:g} std {within}/{draws}, "
              f"held-out 3-D RMS median {np.median(held):.3f} mm, worst {held.max():.4g} mm, "
              f"above 1 mm {int(np.sum(held > 1.0))}/{draws}; iterations median {np.median(iterations):g}, "
              f"{iterations.min()}-{iterations.max()}")


if __name__ == "__main__":
    args = sys.argv[1:]
    main(*(kind(a) for kind, a in zip((int, int, float), args)))
