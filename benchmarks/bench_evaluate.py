"""Benchmark: one Pinocchio pass of kinid (tool point + Jacobians of every pose) against the raw Pinocchio calls.

``kinid.identification.machine.evaluate`` computes, for N poses, the tool
point in the workpiece frame and its derivatives with respect to every error
joint and axis. The floor is the Pinocchio calls themselves: per pose
``computeJointJacobians``, two ``updateFramePlacement`` and two
``getFrameJacobian`` — the same calls with the same configurations, nothing
else. The ratio is the cost of kinid's own array work around them (target:
at most 1.5). Best of 15 runs each, interleaved, in one process.

Run: ``python benchmarks/bench_evaluate.py``
"""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

from kinid.identification.machine import _configurations, axes_to_si, evaluate, load_machine  # noqa: E402
from kinid.identification.simulate import patent_plan  # noqa: E402
from kinid.urdf import path  # noqa: E402


def main() -> None:
    for name in ("five_axis_bc", "five_axis_bhead_c"):
        m = load_machine(path(name))
        axes = np.nan_to_num(patent_plan(m).axes)
        errors = np.zeros(len(m.error_joints))
        qs = _configurations(m, axes_to_si(m, axes), np.zeros((len(axes), len(errors))))
        model, data = m.model, m.model.createData()
        lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED

        def raw():
            for q in qs:
                pin.computeJointJacobians(model, data, q)
                pin.updateFramePlacement(model, data, m.workpiece_frame)
                pin.updateFramePlacement(model, data, m.tool_frame)
                pin.getFrameJacobian(model, data, m.tool_frame, lwa)
                pin.getFrameJacobian(model, data, m.workpiece_frame, lwa)

        def ours():
            evaluate(m, axes, errors)

        raw(), ours()  # warm-up: first calls pay for allocations and caches
        t_raw, t_ours = [], []
        for _ in range(15):
            for f, out in ((raw, t_raw), (ours, t_ours)):
                t = time.perf_counter()
                f()
                out.append(time.perf_counter() - t)
        a, b = min(t_raw), min(t_ours)
        print(f"{name:18s} {len(axes)} poses: raw Pinocchio calls {a * 1e3:6.2f} ms, kinid evaluate {b * 1e3:6.2f} ms, "
              f"ratio {b / a:4.2f} ({len(axes) / b:,.0f} poses/s with Jacobians)")


if __name__ == "__main__":
    main()
