"""``kinid contour``: planar contour error from an image sequence of a ring-coded board (docs/formats.md, "Board file")."""
from __future__ import annotations

import math
import sys

from kinid.errors import DataError
from kinid.options import add_alias
from ..outputs import add_output_options, check_report, staged_report

__all__ = ["register"]


def micrometres(text: str) -> float:
    """``--pixel-um``: a pixel's size given in µm, kept in mm (the unit the tracker works in)."""
    return float(text) * 1e-3


def register(subparsers) -> None:
    """Add the ``contour`` verb to the ``kinid`` command line."""
    p = subparsers.add_parser(
        "contour",
        help="track a ring-coded board through an image sequence and report the contour error",
        description="Monocular contour method: decode the ring-coded marks of every frame, estimate the board's rotation and "
                    "the image scale once from all frames, follow the reference mark (the decoded mark nearest "
                    "the image centre in the first frame) even after it leaves the view, and compare its track "
                    "with the programmed path. TRACK.csv: frame,t_s,x_mm,y_mm,error_um (camera frame: x right, "
                    "y down, mm relative to the first frame; frames not located keep their row with empty "
                    "x_mm, y_mm and error_um).")
    p.add_argument("--data", dest="frames", metavar="DIR",
                   help="folder of image files (read in name order) or a video file")
    p.add_argument("--board", metavar="BOARD.json", help="board description file")
    p.add_argument("--simulate", action="store_true",
                   help="render a circular contour run of a simulated machine (known errors) and measure it: "
                        "measured against true track and contour error; --keep DIR keeps the frames")
    p.add_argument("--keep", metavar="DIR", help="with --simulate: write the frames, board.json and camera.json here")
    p.add_argument("--sim-frames", type=int, default=40, help="with --simulate: frames over one turn (default 40)")
    scale = p.add_mutually_exclusive_group()
    scale.add_argument("--pixel-um", dest="pixel_mm", type=micrometres, metavar="S", help="object-side pixel size, µm")
    scale.add_argument("--camera", metavar="CAMERA.json", help="camera calibration (lens distortion is removed)")
    p.add_argument("--path", choices=("circle", "line", "polyline"), default="circle",
                   help="programmed path (default circle: least-squares circle through the track)")
    p.add_argument("--centre", "--center", dest="centre", metavar="X,Y",
                   help="circle centre in track coordinates, mm (default: fitted)")
    p.add_argument("--radius-mm", dest="radius", type=float, metavar="R", help="circle radius, mm (default: fitted)")
    p.add_argument("--start", metavar="X,Y", help="line start, mm (with --end; default: fitted line)")
    p.add_argument("--end", metavar="X,Y", help="line end, mm")
    p.add_argument("--path-file", metavar="PATH.csv", help="polyline vertices: CSV with columns x_mm,y_mm")
    p.add_argument("--fps", type=float, metavar="F",
                   help="frame rate: t_s = frame / F (default: the video's rate; for a folder t_s is left empty)")
    outputs = add_output_options(
        p, out=("TRACK.csv", "track and contour error per frame (required on measured frames)"),
        plot=("OUT.png", "polar plot of the radial deviation (circle) or error plot"),
        json="print the JSON summary only",
        report=("DIR", "write an HTML report (results, plot) into DIR"))
    p.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    p.add_argument("--scheduler", metavar="ADDRESS|local",
                   help="map the frames on a Dask cluster: its scheduler's address (tcp://host:8786), or 'local' "
                        "for a local cluster of --workers processes (pip install 'kinid[dask]')")
    p.add_argument("--roi-px", metavar="X0,Y0,W,H", help="decode marks only inside this window of each frame")
    p.add_argument("--downsample", default="auto", metavar="N|auto",
                   help="decode on an N-times box-filtered copy of each frame (faster for large marks); "
                        "default auto: 2 when the centre circle keeps a radius of >= 20 px, else 1")
    p.add_argument("--refine", choices=("fit", "centroid"), default="fit",
                   help="mark centre refinement: model fit (default, most accurate) or weighted centroid (faster)")
    p.add_argument("--seed", type=int, default=0, help="with --simulate: seed of the image noise (default 0)")
    p.add_argument("--progress", action="store_true", help="show a progress line even when stderr is not a terminal")
    add_alias(p, "--frames", "--data")
    add_alias(p, "--radius", "--radius-mm")
    add_alias(p, "--pixel-mm", "--pixel-um", reads=float, note=" in µm (1000 x the mm value)")
    p.set_defaults(run=_run, outputs={**outputs, "keep": "replaced folder"})


def _pair(text, option):
    try:
        vals = [float(v) for v in str(text).split(",")]
    except ValueError:
        vals = []
    if len(vals) != 2 or not all(math.isfinite(v) for v in vals):
        raise DataError(f"{option} expects two numbers X,Y in mm, got {text!r}", column=option)
    return tuple(vals)


def _path_from_args(args):
    from .paths import CirclePath, LinePath, PolylinePath, load_polyline

    if args.path == "circle":
        if args.radius is not None and not (math.isfinite(args.radius) and args.radius > 0):
            raise DataError(f"--radius-mm must be a positive number of mm, got {args.radius}", column="--radius-mm")
        centre = _pair(args.centre, "--centre") if args.centre else None
        return CirclePath(centre, args.radius)
    if args.path == "line":
        if (args.start is None) != (args.end is None):
            raise DataError("--path line needs both --start and --end, or neither (fitted line)", column="--start")
        if args.start is None:
            return LinePath()
        return LinePath(_pair(args.start, "--start"), _pair(args.end, "--end"))
    if not args.path_file:
        raise DataError("--path polyline needs --path-file PATH.csv with columns x_mm,y_mm", column="--path-file")
    return PolylinePath(load_polyline(args.path_file))


def _simulate(args) -> int:
    """Render a run of a simulated machine, measure it like real frames, print measured against true. Without
    ``--keep`` the frames go to a temporary folder, removed however the run ends (an error, Ctrl-C)."""
    import shutil
    import tempfile
    from pathlib import Path

    if args.keep:
        return _simulate_in(args, None)
    scratch = Path(tempfile.mkdtemp(prefix="kinid-contour-"))
    try:
        return _simulate_in(args, scratch)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _simulate_in(args, scratch) -> int:
    """:func:`_simulate` with its folder: ``scratch``, or ``--keep``'s listed folder when None."""
    import contextlib
    from pathlib import Path

    import numpy as np

    from kinid.files import write_text
    from kinid.folders import check_listed_folder, listed_folder
    from kinid.vision import make_board, save_board, save_camera
    from .measure import measure_contour, track_csv
    from .paths import contour_error
    from .report import write_report
    from .simulate import circle_motion, render_sequence, simulation_camera
    from .track import FrameSettings

    if not 8 <= args.sim_frames <= 2000:
        raise DataError(f"--sim-frames must be 8 .. 2000, got {args.sim_frames}")
    if args.path != "circle":
        raise DataError(f"--simulate renders a circular run: --path circle, got --path {args.path}", column="--path")
    path = _path_from_args(args)  # --radius-mm and --centre, if given, are the nominal circle's
    check_report(args)
    board = make_board(rows=10, cols=10, pitch_mm=6.0, center_d_mm=2.0, ring_inner_d_mm=3.6, ring_outer_d_mm=5.2)
    camera = simulation_camera((512, 512), 0.03, k1=-0.05)
    motion = circle_motion(args.sim_frames, 8.0, fps=80.0, lag_deg=0.03, spike_um=6.0, spike_width_deg=20.0,
                           scale_x_ppm=150.0)
    if args.keep:
        check_listed_folder(args.keep)
        kept = listed_folder(args.keep, written_by="kinid contour --simulate --keep")
    else:
        kept = contextlib.nullcontext(scratch)
    with kept as folder:  # --keep DIR: rendered and measured in a new folder that replaces DIR whole at the end
        frames = folder / "frames"
        frames.mkdir()
        seq = render_sequence(frames, board, camera, motion, noise_sigma=2.0, rng=np.random.default_rng(args.seed))
        save_board(board, folder / "board.json")
        save_camera(camera, folder / "camera.json")
        m = measure_contour(frames, board, FrameSettings(camera=camera, bits=board.bits), path, fps=80.0,
                            workers=args.workers, scheduler=args.scheduler)
    if args.keep:
        folder = Path(args.keep)
        frames = folder / "frames"
    if args.out:
        write_text(args.out, track_csv(m))
    if args.plot:
        from .report import plot_contour

        plot_contour(m, args.plot)
    if args.report:
        with staged_report(args) as staged:
            write_report(m, staged, frames=frames if args.keep else "not kept (--keep DIR keeps them)",
                         board=folder / "board.json", scale=folder / "camera.json",
                         simulated=True)
    ok = m.track.located
    track_err = np.sqrt(np.mean(np.sum(((m.track.xy_mm - seq.track_mm) * 1e3)[ok] ** 2, axis=1)))
    truth = contour_error(seq.track_mm, path)
    summary = {"frames": int(len(ok)), "located": int(ok.sum()), "track_rms_error_um": float(track_err),
               "contour_rms_um": m.contour.rms_um, "true_contour_rms_um": truth.rms_um,
               "contour_max_um": m.contour.max_um, "true_contour_max_um": truth.max_um}
    if args.json:
        from kinid.files import strict_json

        print(strict_json(summary))
    else:
        print(f"simulated circular run: radius 8 mm, {len(ok)} frames of 512 x 512 px at 30 µm, lens distortion, "
              f"a 0.03° servo lag, 150 ppm X scale error and 6 µm reversal spikes; seed {args.seed}")
        print(f"{'':24}{'measured':>12}{'true':>12}")
        print(f"{'contour error RMS (µm)':<24}{m.contour.rms_um:12.3f}{truth.rms_um:12.3f}")
        print(f"{'contour error max (µm)':<24}{m.contour.max_um:12.3f}{truth.max_um:12.3f}")
        print(f"track against the truth: {track_err:.3f} µm RMS over {int(ok.sum())} located frames")
        where = f"kept in {folder}" if args.keep else "rendered in a temporary folder"
        print(f"frames, board.json and camera.json {where}")
        if args.keep:
            print(f"measure them as real frames: kinid contour --data {frames} --board {folder / 'board.json'} "
                  f"--camera {folder / 'camera.json'} --out TRACK.csv")
    return 0


def _run(args) -> int:
    from pathlib import Path

    from kinid.files import strict_json, write_text
    from kinid.progress import Progress
    from kinid.vision import load_board

    if args.simulate:
        return _simulate(args)
    missing = [o for o, v in (("--data", args.frames), ("--board", args.board), ("--out", args.out)) if not v]
    if missing or (args.pixel_mm is None and args.camera is None):
        need = missing + ([] if args.pixel_mm is not None or args.camera is not None else ["--pixel-um or --camera"])
        raise DataError(f"measured frames need {', '.join(need)} (or run --simulate to learn the method)")
    check_report(args)

    from .frames import open_frames
    from .measure import measure_contour, track_csv
    from .report import report_text, write_report
    from .track import FrameSettings

    board = load_board(args.board)
    camera = None
    if args.camera:
        from kinid.vision import load_camera

        camera = load_camera(args.camera)
    if args.pixel_mm is not None and not (math.isfinite(args.pixel_mm) and args.pixel_mm > 0):
        raise DataError(f"--pixel-um must be a positive number of µm, got {args.pixel_mm * 1e3:g}",
                        column="--pixel-um")
    if args.fps is not None and not (math.isfinite(args.fps) and args.fps > 0):
        raise DataError(f"--fps must be a positive number, got {args.fps}", column="--fps")
    if args.downsample == "auto":
        downsample = None
    else:
        try:
            downsample = int(args.downsample)
        except ValueError:
            downsample = 0
        if downsample < 1:
            raise DataError(f"--downsample must be 'auto' or an integer >= 1, got {args.downsample!r}", column="--downsample")
    if args.workers < 1:
        raise DataError(f"--workers must be >= 1, got {args.workers}", column="--workers")
    roi = None
    if args.roi_px:
        try:
            roi = tuple(int(v) for v in args.roi_px.split(","))
        except ValueError:
            roi = ()
        if len(roi) != 4 or roi[2] < 1 or roi[3] < 1:
            raise DataError(f"--roi-px expects four integers X0,Y0,W,H with W,H >= 1, got {args.roi_px!r}",
                            column="--roi-px")
    path = _path_from_args(args)
    settings = FrameSettings(pixel_mm=args.pixel_mm, camera=camera, bits=board.bits, refine=args.refine, roi_px=roi,
                             downsample=downsample)
    source = open_frames(args.frames)
    progress = Progress(source.count, "frames", enabled=True if args.progress else None)
    try:
        m = measure_contour(source, board, settings, path, fps=args.fps, workers=args.workers, progress=progress,
                            scheduler=args.scheduler)
    finally:
        progress.close()
    write_text(args.out, track_csv(m))
    if args.plot:
        from .report import plot_contour

        plot_contour(m, args.plot)
    if args.report:
        with staged_report(args) as staged:
            write_report(m, staged, frames=args.frames, board=args.board,
                         scale=f"--pixel-um {args.pixel_mm * 1e3:g}" if args.pixel_mm else Path(args.camera))
    tr = m.track
    if tr.not_located:
        shown = ", ".join(str(k) for k in tr.not_located[:20]) + (" ..." if len(tr.not_located) > 20 else "")
        first = tr.reasons.get(tr.not_located[0], "")
        print(f"kinid contour: {len(tr.not_located)} of {len(tr.located)} frame(s) not located (empty rows in "
              f"{args.out}): {shown} (frame {tr.not_located[0]}: {first})", file=sys.stderr)
    if m.fps is None:
        print("kinid contour: no --fps given and the frames carry no rate; t_s left empty", file=sys.stderr)
    if args.json:
        print(strict_json(m.summary))
        return 0
    print(report_text(m, settings))
    return 0


