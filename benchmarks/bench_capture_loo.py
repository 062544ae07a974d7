"""Benchmark: a motion-capture file of an arm read as it is, leave-one-pose-out, plain and with the prior.

Run: ``python benchmarks/bench_capture_loo.py FILE URDF --tool LINK [--base LINK]`` — FILE the capture system's
table as it was written (a header ``x1, y1, z1, x2, …`` in m, the joints' readings under the URDF's joint names in
m and rad), URDF the robot's description. Public data of others, never part of kinid; measured on the TIAGo set of
FIGAROH's examples (``qualysis_base_hand_calibration.csv`` in
thanhndv212/figaroh-examples/examples/tiago/data/calibration/mocap, 34 poses, four points of the hand's rigid body, the fourth a copy of the third; the
TIAGo URDF of Gepetto/example-robot-data, ``--base base_footprint --tool arm_tool_link``).

The user's route, no hand step: the machine is what ``kinid model`` writes (``identification_urdf``: the chain to
``--tool``, location errors before every joint, set-up of the measurement frame and of the point), the file is read
by kinid's export reader (``read_export``, as ``kinid identify --data FILE``), the model is identify's
(``model_effects``: every target its own point on the tool). Each pose is left out in turn — all its targets'
rows together, so no row of the pose left out is in the fit — and the fit on the others predicts it. Printed, the
3-D RMS of the left-out points:

- every target fitted together (``kinid identify``), plain least squares and with ``--prior`` (its scale and σ
  chosen by the evidence of the training poses only: nested);
- the first target alone (``--target T1``), plain and with the prior: the observation FIGAROH's example fits
  (marker 1's position only);
- beside them, FIGAROH's figures for the same 34 poses as the task that set this benchmark gives them (a
  leave-one-out of FIGAROH's plain fit and of its MAP estimate with the regularisation chosen by cross-validation:
  4.19 mm and 3.87 mm; FIGAROH is not run here and is not a dependency).
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

#: FIGAROH on the same 34 TIAGo poses, leave-one-out 3-D RMS, mm (not run here; see the module docstring).
FIGAROH_PLAIN_MM = 4.19
FIGAROH_MAP_CV_MM = 3.87


def _machine(urdf, tool, base):
    from kinid.files import read_limited_text
    from kinid.identification.model import MAX_URDF_BYTES, identification_urdf, machine_from_urdf

    text = read_limited_text(urdf, what="URDF", max_bytes=MAX_URDF_BYTES)
    return machine_from_urdf(identification_urdf(text, tool=tool, base=base, path=urdf), "capture_kinid.urdf")


def leave_one_pose_out(machine, obs, effects, *, prior: bool) -> tuple:
    """(3-D RMS of the left-out points in µm, that of the first target's alone, the prior scales chosen): every pose
    (its targets' rows together, :func:`pose_folds`) left out in turn, the fit on the others (with the prior: its
    scale and σ chosen on them alone) predicting it."""
    from kinid.identification.fitting import choose_prior, design, fit, pose_folds, prior_std, residuals

    folds, _ = pose_folds(obs, len(obs), 1)
    first = np.array([m == obs.marks[0] for m in obs.marks])
    ss, ss_first, scales = 0.0, 0.0, []
    for rows in folds:
        test = np.isin(np.arange(len(obs)), rows)
        train = obs.subset(~test)
        kw = {}
        if prior:
            choice = choose_prior(machine, train, effects)
            kw = dict(noise_um=choice.noise_um, prior_std=prior_std(machine, effects, choice.scale))
            scales.append(choice.scale)
        result = fit(machine, train, effects, **kw)
        held = obs.subset(test)
        r = residuals(machine, design(machine, effects, held), held, result.theta, jacobian=False)
        ss += float(np.sum(r**2))
        ss_first += float(np.sum(r[first[test]] ** 2))
    return float(np.sqrt(ss / len(obs))), float(np.sqrt(ss_first / first.sum())), scales


def main(argv=None) -> None:
    from threadpoolctl import threadpool_limits

    from kinid.errors import KinidError
    from kinid.identification.data import read_export
    from kinid.identification.fitting import model_effects

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("file", help="the capture system's table, as written")
    p.add_argument("urdf", help="the robot's URDF")
    p.add_argument("--tool", required=True, metavar="LINK", help="the link the markers are fixed to")
    p.add_argument("--base", default=None, metavar="LINK", help="the chain's first link (default: the root)")
    args = p.parse_args(argv)
    try:
        machine = _machine(args.urdf, args.tool, args.base)
        export = read_export(args.file, machine)
    except KinidError as exc:  # a file that is not what it should be: one line, exit 2
        print(f"bench_capture_loo: {exc}", file=sys.stderr)
        sys.exit(2)
    print("\n".join(export.notes()))
    obs = export.observations
    targets = tuple(dict.fromkeys(obs.marks))
    first = obs.subset(np.array([m == targets[0] for m in obs.marks]))
    poses = len(set(obs.lines))
    started = time.perf_counter()
    with threadpool_limits(1):
        rows = []
        for label, o, effects in ((f"{len(targets)} targets together", obs, model_effects(machine, (), targets=targets)),
                                  (f"{targets[0]} alone (FIGAROH's observation)", first, model_effects(machine, ()))):
            plain = leave_one_pose_out(machine, o, effects, prior=False)
            prior = leave_one_pose_out(machine, o, effects, prior=True)
            rows.append((label, plain, prior))
    print(f"\n{poses} poses, leave-one-pose-out 3-D RMS of the left-out points ({time.perf_counter() - started:.0f} s):")
    print(f"{'':44s} {'plain':>9s} {'--prior':>9s}   (every target's points; {targets[0]}'s alone)")
    for label, plain, prior in rows:
        scales = prior[2]
        print(f"{'kinid, ' + label:44s} {plain[0] / 1e3:7.2f} mm {prior[0] / 1e3:7.2f} mm   ({plain[1] / 1e3:.2f}; "
              f"{prior[1] / 1e3:.2f} mm)   prior scales chosen: {', '.join(f'×{s:g}' for s in sorted(set(scales)))} "
              f"(median ×{np.median(scales):g})")
    print(f"{'FIGAROH, marker 1 (as given; not run here)':44s} {FIGAROH_PLAIN_MM:7.2f} mm {FIGAROH_MAP_CV_MM:7.2f} mm"
          "   (MAP, regularisation by cross-validation)")


if __name__ == "__main__":
    main()
