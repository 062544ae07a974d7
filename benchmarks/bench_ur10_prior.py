"""Benchmark: small noisy data — a real UR10e calibration set (23 poses), regularised vs plain identification.

Run: ``python benchmarks/bench_ur10_prior.py ../shared/real/ur10`` (a folder with ``ur10_robot.urdf`` and
``calibration.csv``: the measured marker position x1, y1, z1 in m and the six joint readings in rad; public
data of others, not part of kinid).

The machine is made from the robot's URDF by ``kinid model`` (chain to ``wrist_3_link``, location errors
before every joint, set-up of the measurement frame and of the marker). Printed, leave-one-out over the 23
poses (3-D RMS of the marker position of the pose left out):

- the plain least-squares fit of the full model;
- a fit of the measurement frame and the marker alone (the set-up joints W and T);
- the maximum a posteriori fit with kinid's prior (kinid.identification.fitting.prior), its scale and σ chosen by
  the marginal likelihood of the 22 training poses only (nested: the left-out pose never chooses them),
  and, for comparison, with the scale chosen by an inner leave-one-out on the 22;
- beside them, the figure FIGAROH publishes for its MAP estimate with cross-validation on the same 23
  poses: 3.99 mm (FIGAROH is not run here and is not a dependency).
"""
from __future__ import annotations

import csv
import sys
import time
from pathlib import Path

import numpy as np


def main(folder):
    from threadpoolctl import threadpool_limits

    from kinid.identification import default_model, fit
    from kinid.identification.model.machine import machine_from_urdf
    from kinid.identification.data.observations import Observations
    from kinid.identification.fitting.prior import choose_prior, prior_std
    from kinid.identification.fitting.residuals import design, residuals
    from kinid.identification.model.urdf_import import identification_urdf

    folder = Path(folder)
    machine = machine_from_urdf(identification_urdf((folder / "ur10_robot.urdf").read_text(), tool="wrist_3_link"),
                                "ur10_kinid.urdf")
    rows = list(csv.DictReader(open(folder / "calibration.csv")))
    w = np.array([[float(r[k]) * 1e3 for k in ("x1", "y1", "z1")] for r in rows])
    axes = np.array([[np.degrees(float(r[a.joint])) for a in machine.axes] for r in rows])
    n = len(w)
    obs = Observations(tuple(f"P{i}" for i in range(n)), w, axes, None, {}, tuple(range(2, n + 2)), str(folder))
    full = list(default_model(machine))
    frame = [e for e in full if machine.error_joint(e.code).axis in ("W", "T")]

    def predict(effects, train, test, **kw):
        result = fit(machine, obs.subset(train), effects, **kw)
        te = obs.subset(test)
        r = residuals(machine, design(machine, effects, te), te, result.theta, jacobian=False)
        return float(np.sum(r**2)), result

    started = time.perf_counter()
    ss = {"plain": 0.0, "frame": 0.0, "prior": 0.0, "prior_cv": 0.0}
    chosen, chosen_cv, worst_unphysical = [], [], []
    with threadpool_limits(1):
        for i in range(n):
            train, test = np.arange(n) != i, np.arange(n) == i
            ss["plain"] += predict(full, train, test)[0]
            ss["frame"] += predict(frame, train, test)[0]
            choice = choose_prior(machine, obs.subset(train), full)
            e, result = predict(full, train, test, noise_um=choice.noise_um,
                                prior_std=prior_std(machine, full, choice.scale))
            ss["prior"] += e
            chosen.append(choice.scale)
            cv = choose_prior(machine, obs.subset(train), full, method="cross-validation")
            ss["prior_cv"] += predict(full, train, test, noise_um=cv.noise_um,
                                      prior_std=prior_std(machine, full, cv.scale))[0]
            chosen_cv.append(cv.scale)
            worst_unphysical.append(len(result.implausible()))
    loo = {k: np.sqrt(v / n) / 1e3 for k, v in ss.items()}
    print(f"UR10e, {n} real poses ({folder}), leave-one-out 3-D RMS of the marker position "
          f"({time.perf_counter() - started:.0f} s):")
    print(f"  plain least squares, full model ({len(full)} effects)      {loo['plain']:.3f} mm")
    print(f"  measurement frame and marker only ({len(frame)} effects)     {loo['frame']:.3f} mm")
    print(f"  kinid prior, scale and σ by the evidence (nested)   {loo['prior']:.3f} mm   scales chosen: "
          f"{', '.join(f'{s:g}' for s in sorted(set(chosen)))} (median {np.median(chosen):g}); fits with "
          f"implausible values: {sum(1 for x in worst_unphysical if x)}")
    print(f"  kinid prior, scale by inner leave-one-out (nested)  {loo['prior_cv']:.3f} mm   scales chosen: "
          f"{', '.join(f'{s:g}' for s in sorted(set(chosen_cv)))}")
    print("  FIGAROH MAP with cross-validation (published, same 23 poses)  3.99 mm")
    whole = choose_prior(machine, obs, full)
    print(f"on all {n} poses: {whole.describe()}")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
