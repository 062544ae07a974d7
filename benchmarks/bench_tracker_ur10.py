"""Benchmark: a real UR10 measured by a laser tracker, read as the instrument exported it.

Run: ``python benchmarks/bench_tracker_ur10.py FOLDER [--series B] [--train N] [--folds K]`` where FOLDER holds the public
series of christianlandgraf/ipa-robot-accuracy (``series_B_measurements_joint_configurations.csv``,
``series_C_measurements_random_poses.csv``, ``series_D_measurements_iso_cubes.csv``, ``series_B_Trafo_TM_F_init.txt``)
and ``ur10_robot.urdf`` (example-robot-data). Nothing of it is in this repository.

As a user would, with no hand step: ``kinid model`` on the URDF (base_link -> tool0, the probe point from the Trafo
file as ``--tool-offset-mm``), ``kinid identify`` on series B as exported (';', decimal commas, joints in rad under
the URDF's names, the point in mm) — plain and with ``--prior --no-check``, each without and with the arm's sag under
its weight (``--add EB0J2:sag:J3 EB0J2:sag:J4 EB0J3:sag:J4``: the upper arm and forearm give by a compliance times
the torque of the weight they carry) — and the plain fit with the gravity compliance (``--add EB0J2:gravity``: J2,
J3, J4 each by its compliance times the torque of the URDF's masses beyond it) — then the fitted arm predicts the other series. ``--series C`` trains on C
instead (and so on). The tracker stood elsewhere for each series, so the held-out figure fits only the measurement frame
(a rigid transform, 6 numbers, kinid.identification.fitting.rigid_transform) to each series and reports the 3-D RMS
of what is left (mm). Then a K-fold (default 10) on the series trained on: each fold's fit (the prior's scale
and σ chosen once on all of it, so the folds share that choice) predicts its held-out poses in the same tracker frame; the plain fit with the
sag too.
``--auto``: also ``kinid identify --auto`` (the effects it adds are printed; minutes, a fit and a held-out check a
step). Printed: the exit status, iterations and convergence of every fit; the held-out 3-D RMS of the other series
and the folds (``--folds 0`` skips them).
``--orientation``: the T-Mac's measured orientation too (its ``measurement_rx/_ry/_rz``, Euler XYZ in degrees, the
probe turned on the flange as the Trafo file's rotation says: ``--orientation-mount-deg``), three rows more per pose
(docs/formats.md, "Measured orientation"); without it the fits read the points only (``--orientation off``), as
before. Printed besides: the check of the angles at the start, the fit's orientation residuals against the points'
(identify's line), and on each other series the orientation left once the tracker's frame is refitted to its points
(RMS per component, µrad, against the series' stated σ). The folds fit the points only.
Published reference (Landgraf et al., IEEE CASE 2021 data; the frame fitted first): 0.40-0.49 mm held-out.
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

#: The arm's sag under its weight: J2 under the weights at J3 (the upper arm) and J4 (the forearm), J3 under J4's.
SAG = ("EB0J2:sag:J3", "EB0J2:sag:J4", "EB0J3:sag:J4")
#: The arm's gravity compliance: J2, J3, J4 each by its compliance times the torque of the URDF's masses beyond it.
GRAVITY = "EB0J2:gravity"
SERIES = {"B": "series_B_measurements_joint_configurations.csv", "C": "series_C_measurements_random_poses.csv",
          "D": "series_D_measurements_iso_cubes.csv"}


def probe_offset_mm(trafo: Path) -> tuple:
    """The probe point in the flange (tool0) frame, mm, from the 4 × 4 transform of the Trafo file.

    The file's matrix [R t] is read as the flange's pose in the probe's frame, so the point is −Rᵀt: (0.000, 0.000,
    109.000) mm, on the flange's axis. (Read the other way, t = (0, 0.087, −109) mm, the fit's start moves the point
    on the tool by about 200 mm instead of 16 mm.)
    """
    values = [float(v) for v in trafo.read_text().replace("1.-", "1. -").split()]
    T = np.array(values[:16]).reshape(4, 4)
    return tuple(float(v) for v in -T[:3, :3].T @ T[:3, 3])


def probe_mount_deg(trafo: Path) -> tuple:
    """The probe's orientation on the flange (tool0), Euler XYZ, deg, from the Trafo file's rotation: the measured
    orientation is the flange's times this turn (checked on the data: read so, series B's angles lie 0.2° RMS from
    the nominal arm's at the frame fitted to the points; with no turn, 90°)."""
    from scipy.spatial.transform import Rotation

    values = [float(v) for v in trafo.read_text().replace("1.-", "1. -").split()]
    R = np.array(values[:16]).reshape(4, 4)[:3, :3]
    U, _, Vt = np.linalg.svd(R)  # the file's rotation to 8 digits: the nearest rotation
    return tuple(float(v) for v in Rotation.from_matrix(U @ Vt).as_euler("XYZ", degrees=True))


def held_out_orientation_urad(machine, effects, theta, obs, turned) -> tuple:
    """(RMS per component of the orientation left on ``turned``'s poses, µrad; their median stated σ, µrad) once the
    tracker's frame is the rigid transform of ``obs``'s points (the same poses, in the same order)."""
    from kinid.identification.fitting import design, residuals, rigid_transform, rotation_residual_urad, tool_rotations
    from kinid.identification.fitting import joint_values

    d = design(machine, effects, obs)
    th = np.array(theta, float)
    th[[i for i, n in enumerate(d.param_names()) if n.endswith("0W")]] = 0.0
    p = obs.w_mm + residuals(machine, d, obs, th, jacobian=False) / 1e3
    R, _ = rigid_transform(p, obs.w_mm)
    rows = turned.observations.rotation_rows
    poses = turned.observations.subset(rows)
    R_model = R @ tool_rotations(machine, poses.axes, joint_values(machine, design(machine, effects, poses), th))
    omega = rotation_residual_urad(R_model, poses.rotations)
    return float(np.sqrt(np.mean(omega**2))), float(np.median(turned.orientation["std_urad"]))


def kinid(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "kinid", *map(str, args)], capture_output=True, text=True)


def held_out_setup_mm(machine, effects, theta, obs, *, point: bool) -> float:
    """3-D RMS (mm) of ``obs`` predicted by the fitted arm once its measurement frame (a rigid transform, 6 numbers)
    and, with ``point``, also the probe point on the tool (3 more) are fitted to them: a new set-up."""
    from kinid.identification.fitting import design, residuals, rigid_transform

    d = design(machine, effects, obs)
    names = d.param_names()
    th = np.array(theta, float)
    th[[i for i, n in enumerate(names) if n.endswith("0W")]] = 0.0  # the arm's points in its base frame

    def points(values):
        return obs.w_mm + residuals(machine, d, obs, values, jacobian=False) / 1e3

    p0 = points(th)
    G = np.zeros((len(obs), 3, 3))  # the tool point's translations EX0T, EY0T, EZ0T enter linearly (1 mm each)
    if point:
        for k, code in enumerate(("EX0T", "EY0T", "EZ0T")):
            step = th.copy()
            step[names.index(code)] += 1000.0
            G[:, :, k] = points(step) - p0
    s = np.zeros(3)
    for _ in range(20 if point else 1):  # alternate: the frame by the rigid fit, the point by linear least squares
        R, t = rigid_transform(p0 + G @ s, obs.w_mm)
        A = np.einsum("ij,njk->nik", R, G).reshape(-1, 3)
        b = (obs.w_mm - t - (p0 @ R.T)).reshape(-1)
        if point:
            s = np.linalg.lstsq(A, b, rcond=None)[0]
    R, t = rigid_transform(p0 + G @ s, obs.w_mm)
    return float(np.sqrt(np.mean(np.sum(((p0 + G @ s) @ R.T + t - obs.w_mm) ** 2, axis=1))))


def held_out_mm(machine, effects, theta, obs) -> float:
    """3-D RMS (mm) of ``obs`` predicted by the fit as it is (its own measurement frame)."""
    from kinid.identification.fitting import design, residuals

    r = residuals(machine, design(machine, effects, obs), obs, np.asarray(theta), jacobian=False).reshape(-1, 3)
    return float(np.sqrt(np.mean(np.sum(r**2, axis=1)))) / 1e3


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--series", choices=sorted(SERIES), default="B", help="the series trained on (default B)")
    ap.add_argument("--train", type=int, default=None, help="fit on its first N poses (default all)")
    ap.add_argument("--folds", type=int, default=10)
    ap.add_argument("--orientation", action="store_true", help="fit the measured orientation too (three rows a pose)")
    ap.add_argument("--auto", action="store_true", help="also `kinid identify --auto` (minutes: a fit a step)")
    args = ap.parse_args(argv)
    from kinid.identification.data import read_export
    from kinid.identification.fitting import PRIOR_UM, PRIOR_URAD, choose_prior, fit, load_fit, model_effects, prior_std
    from kinid.identification.model import load_machine

    folder = args.folder
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        offset = probe_offset_mm(folder / "series_B_Trafo_TM_F_init.txt")
        print(f"probe point on tool0 from the Trafo file: {', '.join(f'{v:.3f}' for v in offset)} mm")
        urdf = tmp / "ur10_kinid.urdf"
        out = kinid("model", "--urdf", folder / "ur10_robot.urdf", "--base", "base_link", "--tool", "tool0",
                    "--tool-offset-mm", *(f"{v:.4f}" for v in offset), "--out", urdf)
        print(f"kinid model: exit {out.returncode}; {out.stdout.splitlines()[0] if out.stdout else out.stderr}")
        name = args.series
        train = folder / SERIES[name]
        if args.train:
            lines = train.read_text().splitlines()
            train = tmp / f"{name}_train.csv"
            train.write_text("\n".join(lines[: args.train + 1]) + "\n")
        machine = load_machine(urdf)
        mount = probe_mount_deg(folder / "series_B_Trafo_TM_F_init.txt")
        turn = ["--orientation-mount-deg", *(f"{v:.6f}" for v in mount)] if args.orientation else ["--orientation", "off"]
        series = {name: read_export(folder / SERIES[name], machine, orientation="off").observations for name in SERIES}
        turned = {name: read_export(folder / SERIES[name], machine, orientation_mount_deg=mount) for name in SERIES}
        if args.orientation:
            from kinid.identification.fitting import check_orientation

            print(f"probe mount (Euler XYZ) from the Trafo file: {', '.join(f'{v:.4f}' for v in mount)}°")
            for other in SERIES:
                print(f"  {other}: {check_orientation(machine, turned[other]).line}")
        routes = [[], ["--prior", "--no-check"], ["--add", *SAG], ["--prior", "--no-check", "--add", *SAG],
                  ["--add", GRAVITY]]
        for extra in routes + ([["--auto"]] if args.auto else []):
            t0 = time.perf_counter()
            out = kinid("identify", "--machine", urdf, "--data", train, "--out", tmp / "fit.json", *turn, *extra)
            last = (out.stderr.strip().splitlines() or [""])[-1] if out.returncode else "fit written"
            print(f"kinid identify {' '.join(extra) or '(plain)'} on {name}: exit {out.returncode} in "
                  f"{time.perf_counter() - t0:.1f} s; {last[-160:]}")
            if out.returncode:
                continue
            loaded = load_fit(tmp / "fit.json")
            effects, theta = loaded.effects, loaded.theta
            trained = f"the first {args.train} trained on" if args.train else "all trained on"
            if "--auto" in extra:
                print(f"  added: {' '.join(e.name for e in effects if ':' in e.name) or 'nothing'}")
            print(f"  {loaded.iterations} iterations, converged: {loaded.success}; {name} ({len(series[name])} poses, "
                  f"{trained}) 3-D RMS {held_out_mm(machine, effects, theta, series[name]):.3f} mm")
            for line in out.stdout.splitlines():
                if line.startswith("orientation residuals:"):
                    print(f"  {line}")
            for other in sorted(set(SERIES) - {name}):
                frame, both = (held_out_setup_mm(machine, effects, theta, series[other], point=p) for p in (False, True))
                rot, stated = held_out_orientation_urad(machine, effects, theta, series[other], turned[other])
                print(f"  {other} held out ({len(series[other])} poses): 3-D RMS {frame:.3f} mm with the tracker's "
                      f"frame refitted, {both:.3f} mm with the frame and the probe point refitted; orientation left "
                      f"{rot:.0f} µrad RMS per component (stated σ {stated:.0f} µrad, median)")
    if not args.folds:
        return 0
    # K-fold on the series: one prior choice on all of it, then a fit per fold
    b = series[name].subset(np.arange(args.train or len(series[name])))
    effects = list(model_effects(machine, []))
    choice = choose_prior(machine, b, effects)
    fold = np.random.default_rng(0).permutation(len(b)) % args.folds
    routes = (("plain", effects, {}),
              (f"prior ×{choice.scale:g}, σ {choice.noise_um:.0f} µm chosen on all of {name}", effects,
               dict(noise_um=choice.noise_um, prior_std=prior_std(machine, effects, choice.scale, PRIOR_UM, PRIOR_URAD))),
              ("plain with the sag", list(model_effects(machine, SAG)), {}))
    for label, effects, kw in routes:
        rms, its, ok = [], [], []
        t0 = time.perf_counter()
        for k in range(args.folds):
            res = fit(machine, b.subset(fold != k), effects, **kw)
            rms.append(held_out_mm(machine, effects, res.theta, b.subset(fold == k)))
            its.append(res.iterations)
            ok.append(res.success)
        print(f"{args.folds}-fold on {name}, {label} ({time.perf_counter() - t0:.0f} s): held-out 3-D RMS mean "
              f"{np.mean(rms):.3f} mm (folds {min(rms):.3f}-{max(rms):.3f}); iterations {min(its)}-{max(its)}; "
              f"converged {sum(ok)}/{args.folds}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
