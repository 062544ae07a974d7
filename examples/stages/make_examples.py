"""Make the measured-input examples of the stage commands from their simulators (deterministic).

    .venv/bin/python examples/stages/make_examples.py --out examples/stages

- ``backlash/``: a run of the backlash plan (``kinid backlash --plan-out``) on the simulated X-Y-θ stage
  (backlash X 4 µm, Y 3 µm, θ 0.01°; 5 µm pixels; camera at 7°), its images and its log;
- ``uvw_moves.csv``: the bidirectional test plan of each UVW actuator, commanded and measured (lead 2 mm);
- ``dual_axis.csv``: one round of the dual-axis method on the simulated gantry (both Y axes stepping together,
  no compensation yet): camera Y and the plate's shift in the image.

Each file's truth is printed, and written beside it as ``*_truth.json`` (for the tests, not for kinid).
"""
import argparse
import csv
import json
from pathlib import Path

import cv2
import numpy as np


def backlash(folder: Path):
    from kinid.stages.backlash import SimulatedStage, calibrate

    folder.mkdir(parents=True, exist_ok=True)
    stage = SimulatedStage(pixel_mm=0.005, camera_angle_deg=7.0, backlash_x_mm=0.004, backlash_y_mm=0.003,
                           backlash_theta_deg=0.01, theta_centre_mm=(-12.0, 8.0), noise_sigma=1.0,
                           image_shape=(240, 320), rng=np.random.default_rng(1))
    rows = []

    class Recording:
        position = (0.0, 0.0, 0.0)

        def move_to(self, x, y, t):
            stage.move_to(x, y, t)
            rows.append([len(rows) + 1, f"{x:.6f}", f"{y:.6f}", f"{t:.6f}", 0, ""])

        def grab(self):
            img = stage.grab()
            name = f"move_{len(rows):03d}.png"
            cv2.imwrite(str(folder / name), img, [cv2.IMWRITE_PNG_COMPRESSION, 9])
            rows[-1][4], rows[-1][5] = 1, name
            return img

    calibrate(Recording(), travel_mm=0.4, travel_deg=2.0)
    with open(folder / "log.csv", "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["move", "x_mm", "y_mm", "theta_deg", "photo", "image"])
        w.writerows(rows)
    truth = {"backlash_x_um": 4.0, "backlash_y_um": 3.0, "backlash_theta_deg": 0.01, "pixel_um": 5.0,
             "camera_rotation_deg": 7.0, "travel_mm": 0.4, "travel_deg": 2.0}
    (folder / "truth.json").write_text(json.dumps(truth, indent=1) + "\n")
    return truth


def uvw(path: Path):
    from dataclasses import asdict

    from kinid.stages.uvw import SimulatedUVWStage
    from kinid.stages.uvw.calibrate import measure_plan, plan_positions

    stage = SimulatedUVWStage(noise_um=0.1, rng=np.random.default_rng(2))
    rows = []
    for actuator in ("X1", "X2", "Y"):
        cmds, dirs, meas = measure_plan(stage.move, actuator, plan_positions(2000.0), repeats=2)
        rows += [[actuator, f"{c:.3f}", int(d), f"{m:.4f}"] for c, d, m in zip(cmds, dirs, meas)]
    with open(path, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["actuator", "command_um", "direction", "measured_um"])
        w.writerows(rows)
    truth = {"lead_um": 2000.0, "noise_um": 0.1, **{a: asdict(t) for a, t in stage.truth.items()}}
    path.with_name(path.stem + "_truth.json").write_text(json.dumps(truth, indent=1, default=float) + "\n")
    return truth


def dual_axis(path: Path):
    from kinid.stages.dual_axis import SimulatedGantry, calibrate

    g = SimulatedGantry(rng=np.random.default_rng(3))
    m = g.true_pixel_to_mm  # in practice measured (docs/dual_axis.md); the example uses the truth
    y0, head0, step, n = 0.0, (0.0, 0.0), 10.0, 20
    table = calibrate(g, y0, head0, step, n, m, spec_um=1e9, max_rounds=1)  # one round, table zero in use
    shift_px = -(table.history[0].offsets_um * 1e-3) @ np.linalg.inv(m).T
    with open(path, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["camera_y_mm", "shift_x_px", "shift_y_px"])
        for y, (sx, sy) in zip(table.y_mm, shift_px):
            w.writerow([f"{y:.3f}", f"{sx:.4f}", f"{sy:.4f}"])
    truth = {"pixel_to_mm": m.tolist(),
             "true_correction_um": [(np.asarray(g.true_correction_mm(y0, head0, y)) * 1e3).tolist() for y in table.y_mm]}
    path.with_name(path.stem + "_truth.json").write_text(json.dumps(truth, indent=1) + "\n")
    return {"pixel_to_mm": truth["pixel_to_mm"]}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    out = Path(args.out)
    print("backlash:", backlash(out / "backlash"))
    print("uvw:", uvw(out / "uvw_moves.csv"))
    print("dual-axis:", dual_axis(out / "dual_axis.csv"))


if __name__ == "__main__":
    main()
