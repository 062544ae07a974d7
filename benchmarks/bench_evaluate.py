"""Benchmark: one Pinocchio pass of kinid (tool point + Jacobians of every pose) against raw Pinocchio calls.

kinid's pass makes one Pinocchio call per pose (``computeJointJacobians``) and
forms the two frames' Jacobians from the world-frame joint Jacobian for all
poses at once; the floor below is the straightforward use of Pinocchio.

``kinid.identification.machine.evaluate`` computes, for N poses, the tool
point in the workpiece frame and its derivatives with respect to every error
joint and axis. The floor is the Pinocchio calls themselves: per pose
``computeJointJacobians``, two ``updateFramePlacement`` and two
``getFrameJacobian`` — the same calls with the same configurations, nothing
else — and the same calls with their results copied into arrays, which any
use of them needs. The ratios are the cost of kinid's own array work around
them. Best of 15 runs each, interleaved, in one process.

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

        n = len(qs)
        R, pw, pt = np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3))
        Jt, Jw = np.empty((n, 6, model.nv)), np.empty((n, 6, model.nv))

        def raw_read():  # the same calls, their results copied out (what any use of them needs)
            for i, q in enumerate(qs):
                pin.computeJointJacobians(model, data, q)
                oMw = pin.updateFramePlacement(model, data, m.workpiece_frame)
                R[i], pw[i] = oMw.rotation, oMw.translation
                pt[i] = pin.updateFramePlacement(model, data, m.tool_frame).translation
                Jt[i] = pin.getFrameJacobian(model, data, m.tool_frame, lwa)
                Jw[i] = pin.getFrameJacobian(model, data, m.workpiece_frame, lwa)

        def ours():
            evaluate(m, axes, errors)

        raw(), raw_read(), ours()  # warm-up: first calls pay for allocations and caches
        t_raw, t_read, t_ours = [], [], []
        for _ in range(15):
            for f, out in ((raw, t_raw), (raw_read, t_read), (ours, t_ours)):
                t = time.perf_counter()
                f()
                out.append(time.perf_counter() - t)
        a, r, b = min(t_raw), min(t_read), min(t_ours)
        print(f"{name:18s} {len(axes)} poses: Pinocchio calls {a * 1e3:5.2f} ms, calls + results copied {r * 1e3:5.2f} ms, "
              f"kinid evaluate {b * 1e3:5.2f} ms: {b / a:4.2f}x the calls, {b / r:4.2f}x calls + copies "
              f"({len(axes) / b:,.0f} poses/s)")


if __name__ == "__main__":
    main()
