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

The floor is the Pinocchio calls ``evaluate`` makes: ``forwardKinematics``, one per pose (counted during a call,
checked here), made bare on the same configurations. For reference only: ``computeJointJacobians`` per pose
(what kinid called before), the same plus copying ``oMi[parent of workpiece]``, ``oMi[parent of tool]`` and
``data.J`` (what it read then), and the old floor with two ``updateFramePlacement`` and two ``getFrameJacobian``
per pose. The ratio to the floor is the cost of kinid's own work around it (argument checks, building the
configurations, copying the placements, frame placements and derivatives in numpy). Each machine twice: whole,
and reduced to the error joints of its default model (``fit_pass.reduced``: what a fit's passes evaluate, only
those joints' columns). CPU time (``time.process_time``), best of 15 interleaved runs, one process, one BLAS thread.

Run: ``python benchmarks/bench_evaluate.py``
"""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

from dataclasses import replace  # noqa: E402

from kinid.identification.fitting.fit_pass import reduced  # noqa: E402
from kinid.identification.fitting.residuals import design  # noqa: E402
from kinid.identification.model.effects import default_model  # noqa: E402
from kinid.identification.model.machine import _configurations, axes_to_si, evaluate, load_machine  # noqa: E402
from kinid.identification.fitting.simulate import patent_plan  # noqa: E402
from kinid.urdf import path  # noqa: E402


def main() -> None:
    print(f"pinocchio {pin.__version__}, numpy {np.__version__}")
    for name in ("five_axis_bc", "five_axis_bhead_c"):
        full = load_machine(path(name))
        plan = patent_plan(full)
        axes = np.nan_to_num(plan.axes)
        small = reduced(full, design(full, default_model(full), replace(plan, axes=axes)))[0]
        measure(name, "whole", full, axes, None)  # every error joint's and axis's column
        measure(name, "reduced", small, axes, np.arange(len(small.error_joints)))  # a fit's pass: its joints only


def measure(name, label, m, axes, columns):
    """Print evaluate's time on ``m`` against the forwardKinematics calls it makes and the reference floors."""
    errors = np.zeros(len(m.error_joints))
    qs = _configurations(m, axes_to_si(m, axes), np.zeros((len(axes), len(errors))))
    model, data = m.model, m.model.createData()
    wf, tf = model.frames[m.workpiece_frame], model.frames[m.tool_frame]
    jw, jt = wf.parentJoint, tf.parentJoint
    lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    n = len(qs)

    def ours():
        evaluate(m, axes, errors, error_columns=columns, axes_jacobian=columns is None)

    ours()  # the first call checks its view of the placements once
    counted = []
    original = pin.forwardKinematics
    pin.forwardKinematics = lambda *a: (counted.append(1), original(*a))[1]
    try:
        ours()
    finally:
        pin.forwardKinematics = original
    assert len(counted) == n, (len(counted), n)

    def fk_calls():  # the floor: what evaluate asks of Pinocchio, one forwardKinematics per pose
        for q in qs:
            pin.forwardKinematics(model, data, q)

    def jj_calls():  # reference: one computeJointJacobians per pose (what kinid called before)
        for q in qs:
            pin.computeJointJacobians(model, data, q)

    Rw, pw = np.empty((n, 3, 3)), np.empty((n, 3))
    Rt, pt = np.empty((n, 3, 3)), np.empty((n, 3))
    J = np.empty((n, 6, model.nv))
    Mw, Mt = data.oMi[jw], data.oMi[jt]  # live views into data, refreshed by every call
    rw, tw, rt, tt, Jv = Mw.rotation, Mw.translation, Mt.rotation, Mt.translation, data.J

    def jj_reads():  # reference: + the results kinid read then: two joint placements and the joint Jacobian
        for i, q in enumerate(qs):
            pin.computeJointJacobians(model, data, q)
            Rw[i], pw[i], Rt[i], pt[i] = rw, tw, rt, tt
            J[i] = Jv

    def old_floor():  # reference: frame placements and frame Jacobians kinid does not compute
        for q in qs:
            pin.computeJointJacobians(model, data, q)
            pin.updateFramePlacement(model, data, m.workpiece_frame)
            pin.updateFramePlacement(model, data, m.tool_frame)
            pin.getFrameJacobian(model, data, m.tool_frame, lwa)
            pin.getFrameJacobian(model, data, m.workpiece_frame, lwa)

    runs = (ours, fk_calls, jj_calls, jj_reads, old_floor)
    for f in runs:
        f()
    # the reads hold what kinid needs: its tool point follows from them
    Rwf = Rw @ wf.placement.rotation
    p_floor = (Rwf.transpose(0, 2, 1) @ ((Rt @ tf.placement.translation + pt)
                                         - (Rw @ wf.placement.translation + pw))[:, :, None])[:, :, 0] * 1e3
    gap = float(np.max(np.abs(p_floor - evaluate(m, axes, errors)[0])))
    assert gap < 1e-9, gap
    t = {f: [] for f in runs}
    for _ in range(15):
        for f, out in t.items():
            s = time.process_time()
            f()
            out.append(time.process_time() - s)
    b, k, a, r, o = (min(t[f]) for f in runs)
    print(f"{name:18s} {label:7s} nq {model.nq:2d}, {n} poses: kinid evaluate {b * 1e3:5.2f} ms ({n / b:,.0f} poses/s); "
          f"floor [forwardKinematics x{n}, the calls it makes] {k * 1e3:5.2f} ms -> kinid {b / k:4.2f}x; "
          f"reference: computeJointJacobians x{n} {a * 1e3:5.2f} ms, + reads {r * 1e3:5.2f} ms, old floor with "
          f"frame placements and Jacobians {o * 1e3:5.2f} ms; floor's tool point = kinid's to {gap:.0e} mm")


if __name__ == "__main__":
    with threadpool_limits(1):
        main()
