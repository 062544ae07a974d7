"""UVW compensation: accuracy of the patent's method and of the fitted model over many random stages, and speed.

Prints, for stages with random scale error, backlash, periodic lead error (random phase) and an optional
bow, the largest and RMS true position error over random 50-2000 µm alignment moves: uncompensated,
the patent's compensation and the model's. Then the time to calibrate (fit) and to compute one command.

Run: python benchmarks/bench_uvw.py
"""
import time

import numpy as np

from kinid.stages.uvw import ACTUATORS, SimulatedUVWStage, calibrate, calibrate_patent
from kinid.stages.uvw.simulate import ActuatorTruth
from kinid.stages.uvw.calibrate import alignment_targets, run_moves


def random_truth(rng, lead_um, bow):
    out = {}
    for name in ACTUATORS:
        a1, a2 = rng.uniform(0.4, 1.2), rng.uniform(0.0, 0.3)
        p1, p2 = rng.uniform(0, 2 * np.pi, 2)
        out[name] = ActuatorTruth(lead_um, scale_ppm=rng.uniform(-500, 500), backlash_um=rng.uniform(1.0, 3.0),
                                  periodic_um=((a1 * np.cos(p1), a1 * np.sin(p1)),
                                               (a2 * np.cos(p2), a2 * np.sin(p2))),
                                  poly_um=(rng.uniform(-0.1, 0.1),) if bow else ())
    return out


def main():
    lead = 2000.0
    print(f"{'case':28s} {'uncomp max/rms':>15s} {'patent max/rms':>15s} {'model max/rms':>15s}"
          "  model<0.6  beats patent")
    for bow in (False, True):
        for noise in (0.1, 0.2):
            rows = {"raw": [], "patent": [], "model": []}
            ok = beats = 0
            stages = 10
            for seed in range(stages):
                rng = np.random.default_rng(seed)
                stage = SimulatedUVWStage(random_truth(rng, lead, bow), noise_um=noise, rng=rng)
                model = calibrate(stage.move, lead_um=lead)
                patent = calibrate_patent(stage.move, lead_um=lead)
                errs = {k: [] for k in rows}
                for name in ACTUATORS:
                    targets = alignment_targets(rng, 200)
                    for k, comp in (("raw", None), ("patent", patent), ("model", model)):
                        errs[k].append(run_moves(stage.move, name, targets, comp, truth=stage.true_um))
                for k in rows:
                    e = np.concatenate(errs[k])
                    rows[k].append((np.abs(e).max(), np.sqrt(np.mean(e ** 2))))
                ok += rows["model"][-1][0] < 0.6
                beats += rows["model"][-1][0] < rows["patent"][-1][0]
            cells = []
            for k in ("raw", "patent", "model"):
                a = np.array(rows[k])
                cells.append(f"{a[:, 0].max():6.2f} / {a[:, 1].mean():5.2f}")
            label = f"{stages} stages, noise {noise} um" + (", bow" if bow else "")
            print(f"{label:28s} {cells[0]:>15s} {cells[1]:>15s} {cells[2]:>15s}  {ok:4d}/{stages}"
                  f"   {beats:4d}/{stages}")

    rng = np.random.default_rng(0)
    stage = SimulatedUVWStage(noise_um=0.1, rng=rng)
    t0 = time.perf_counter()
    model = calibrate(stage.move, lead_um=lead)
    t1 = time.perf_counter()
    targets = alignment_targets(rng, 2000)
    t2 = time.perf_counter()
    for t in targets:
        model.command("X1", t)
    t3 = time.perf_counter()
    print(f"\ncalibrate (3 actuators, {model.moves} simulated moves, BIC over 12 models each): {t1 - t0:.3f} s")
    print(f"command(): {1e6 * (t3 - t2) / len(targets):.1f} µs per call (Newton inversion of the model)")


if __name__ == "__main__":
    main()
