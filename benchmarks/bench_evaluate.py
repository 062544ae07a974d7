"""Benchmark: one Pinocchio pass of kinid (tool point + Jacobians of every pose) against its Pinocchio floor.

``kinid.identification.model.machine.evaluate`` (with ``jacobian=True``) computes,
for N poses, the tool point in the workpiece frame and its derivatives with
respect to every error joint and axis. Its Pinocchio work
(``_evaluate_chunk``) is, per pose, exactly one call,
``pinocchio.forwardKinematics(model, data, q)``, followed by one copy: the
joint placements ``data.oMi`` read through one live view of Pinocchio's array
of placements. The derivatives are formed from those placements for all poses
at once, in numpy (a 1-DOF joint's world-frame Jacobian column is its axis
R_k e_c, and p_k × R_k e_c for a revolute joint: what ``computeJointJacobians``
would put in ``data.J``), only for the columns asked for.

The floors:

- "calls": ``computeJointJacobians`` per pose, nothing else (the Pinocchio
  call that gives the Jacobians; the floor the fit is compared with);
- "calls + reads": the same, plus copying ``oMi[parent of workpiece]``,
  ``oMi[parent of tool]`` (R and p each) and ``data.J`` into preallocated
  arrays, through live views bound once (what kinid did before);
- "forwardKinematics": ``forwardKinematics`` per pose, nothing else (what kinid
  asks of Pinocchio now).

All use the same configurations kinid builds. The floor's reads are checked
to give kinid's tool point. The ratios are the cost of kinid's own work around
the floor (argument checks, building the configurations, frame placements and
derivatives in numpy, splitting the columns into errors and axes). For
reference only, the old floor, which also ran two ``updateFramePlacement`` and
two ``getFrameJacobian`` per pose (work kinid does not do), is timed too.
Best of 15 runs each, interleaved, in one process, one BLAS thread.

Run: ``python benchmarks/bench_evaluate.py``
"""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

from kinid.identification.model.machine import _configurations, axes_to_si, evaluate, load_machine  # noqa: E402
from kinid.identification.fitting.simulate import patent_plan  # noqa: E402
from kinid.urdf import path  # noqa: E402


def main() -> None:
    print(f"pinocchio {pin.__version__}, numpy {np.__version__}")
    for name in ("five_axis_bc", "five_axis_bhead_c"):
        m = load_machine(path(name))
        axes = np.nan_to_num(patent_plan(m).axes)
        errors = np.zeros(len(m.error_joints))
        qs = _configurations(m, axes_to_si(m, axes), np.zeros((len(axes), len(errors))))
        model, data = m.model, m.model.createData()
        wf, tf = model.frames[m.workpiece_frame], model.frames[m.tool_frame]
        jw, jt = wf.parentJoint, tf.parentJoint
        lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        n = len(qs)

        def calls():  # what kinid asks of Pinocchio per pose: one computeJointJacobians
            for q in qs:
                pin.computeJointJacobians(model, data, q)

        Rw, pw = np.empty((n, 3, 3)), np.empty((n, 3))
        Rt, pt = np.empty((n, 3, 3)), np.empty((n, 3))
        J = np.empty((n, 6, model.nv))
        Mw, Mt = data.oMi[jw], data.oMi[jt]  # live views into data, refreshed by every call
        rw, tw, rt, tt, Jv = Mw.rotation, Mw.translation, Mt.rotation, Mt.translation, data.J

        def calls_reads():  # + the results kinid reads: two joint placements and the joint Jacobian
            for i, q in enumerate(qs):
                pin.computeJointJacobians(model, data, q)
                Rw[i], pw[i], Rt[i], pt[i] = rw, tw, rt, tt
                J[i] = Jv

        def old_floor():  # reference only: frame placements and frame Jacobians kinid does not compute
            for q in qs:
                pin.computeJointJacobians(model, data, q)
                pin.updateFramePlacement(model, data, m.workpiece_frame)
                pin.updateFramePlacement(model, data, m.tool_frame)
                pin.getFrameJacobian(model, data, m.tool_frame, lwa)
                pin.getFrameJacobian(model, data, m.workpiece_frame, lwa)

        def fk_calls():  # what kinid asks of Pinocchio per pose now: one forwardKinematics
            for q in qs:
                pin.forwardKinematics(model, data, q)

        def ours():
            evaluate(m, axes, errors)

        calls(), calls_reads(), old_floor(), fk_calls(), ours()  # warm-up: first calls pay for allocations and caches
        # the floor's reads hold what kinid needs: its tool point follows from them
        Rwf = Rw @ wf.placement.rotation
        p_floor = (Rwf.transpose(0, 2, 1) @ ((Rt @ tf.placement.translation + pt)
                                             - (Rw @ wf.placement.translation + pw))[:, :, None])[:, :, 0] * 1e3
        p_kinid = evaluate(m, axes, errors)[0]
        gap = float(np.max(np.abs(p_floor - p_kinid)))
        assert gap < 1e-9, gap

        t = {f: [] for f in (calls, calls_reads, old_floor, fk_calls, ours)}
        for _ in range(15):
            for f, out in t.items():
                s = time.perf_counter()
                f()
                out.append(time.perf_counter() - s)
        a, r, o, k, b = (min(t[f]) for f in (calls, calls_reads, old_floor, fk_calls, ours))
        print(f"{name:18s} {n} poses, nv {model.nv}: kinid evaluate {b * 1e3:5.2f} ms ({n / b:,.0f} poses/s); "
              f"floor [computeJointJacobians x{n}] {a * 1e3:5.2f} ms -> kinid {b / a:4.2f}x; "
              f"floor [computeJointJacobians x{n} + read oMi[{jw}], oMi[{jt}], data.J] {r * 1e3:5.2f} ms -> kinid {b / r:4.2f}x; "
              f"[forwardKinematics x{n}] {k * 1e3:5.2f} ms -> kinid {b / k:4.2f}x; "
              f"(reference: old floor with 2 updateFramePlacement + 2 getFrameJacobian per pose {o * 1e3:5.2f} ms; "
              f"floor's tool point = kinid's to {gap:.0e} mm)")


if __name__ == "__main__":
    with threadpool_limits(1):
        main()
