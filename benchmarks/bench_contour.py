"""Benchmark of ``stages.contour``: frames per second against the patent's 80 fps, memory, and accuracy.

Run: ``python benchmarks/bench_contour.py [--quick]``

Prints, side by side in one run:

1. per-frame cost (PNG decode, mark decoding with both centre refinements) and
   the throughput of the 2-process streaming pipeline (folder of PNG files),
   also decoding on a 2x box-filtered copy (``/2``) and only in the central
   3/4 x 3/4 of the frame (``roi``, as the patent decodes the marks near the centre), at
   1024 x 1024 and 2048 x 2048, for the patent's board (16 mm pitch) and a
   fine board (6 mm pitch), object-side pixel 20-40 um;
2. the parent's resident memory after 1x and 4x as many frames (flat = bounded);
3. accuracy of the reference mark's position far from the marks in view:
   the patent's per-frame two-mark rotation versus the joint rotation of
   :class:`stages.contour.track.TrackBuilder`.
"""
import argparse
import math
import os
import shutil
import tempfile
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402


def _rss_mb():
    """Current resident set size of this process, MB (Linux /proc)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def _render_frames(folder, board, size, pixel_mm, n, rng):
    from kinid.stages.contour.simulate import _PixelMap, render_frame, simulation_camera

    cam = simulation_camera((size, size), pixel_mm, k1=-0.05)
    pm = _PixelMap(cam)
    names = []
    import cv2

    mid = board.mark_mm(board.rows // 2, board.cols // 2)
    for k in range(n):
        origin = (-mid[0] + rng.uniform(-8, 8), -mid[1] + rng.uniform(-8, 8))
        img = render_frame(board, cam, 300.0, origin, 0.7, noise_sigma=2.0, rng=rng, pixel_map=pm)
        name = os.path.join(folder, f"src_{k:03d}.png")
        cv2.imwrite(name, img)
        names.append(name)
    return cam, names


def _sequence(folder, names, count):
    """A folder of ``count`` frames (hard links to the rendered ones, cycling)."""
    os.makedirs(folder, exist_ok=True)
    for k in range(count):
        dst = os.path.join(folder, f"frame_{k:05d}.png")
        if not os.path.exists(dst):
            os.link(names[k % len(names)], dst)
    return folder


def bench_speed(quick):

    from kinid.files import read_image
    from kinid.stages.contour.frames import map_frames, open_frames
    from kinid.stages.contour.track import FrameSettings, process_frame
    from kinid.vision.board import make_board

    patent = make_board()
    fine = make_board(rows=14, cols=14, pitch_mm=6.0, center_d_mm=2.0, ring_inner_d_mm=3.6, ring_outer_d_mm=5.2)
    cases = [("patent 16 mm", patent, 1024, 0.030), ("patent 16 mm", patent, 1024, 0.040),
             ("fine 6 mm", fine, 1024, 0.030), ("patent 16 mm", patent, 2048, 0.020),
             ("fine 6 mm", fine, 2048, 0.020)]
    if quick:
        cases = cases[:1] + cases[3:4]
    rng = np.random.default_rng(0)
    root = tempfile.mkdtemp(prefix="bench_contour_")
    variants = [("fit", 1, False), ("centroid", 1, False), ("fit", 2, False), ("fit", 2, True)]
    print("1. speed (ms per frame in one process; fps: steady-state throughput of the whole pipeline, 2 worker "
          "processes reading PNG files)")
    print(f"{'board':<14}{'size':>6}{'pix um':>7}{'marks':>6}{'roi':>5}{'png ms':>7}{'fit':>7}{'centr':>7}"
          f"{'fit/2':>7}{'roi/2':>7}"
          f"{'fps fit':>8}{'centr':>7}{'fit/2':>7}{'roi/2':>7}{'best vs 80 fps':>15}")
    try:
        for label, board, size, pix in cases:
            src = os.path.join(root, f"{size}_{pix}_{board.pitch_mm}")
            os.makedirs(src)
            n_src = 4 if size >= 2048 else 6
            cam, names = _render_frames(src, board, size, pix, n_src, rng)
            t = time.perf_counter()
            imgs = [read_image(p) for p in names]
            t_png = (time.perf_counter() - t) / len(names) * 1e3
            ms, marks = [], []
            for refine, ds, roi in variants:
                st = FrameSettings(pixel_mm=pix, bits=board.bits, refine=refine, downsample=ds,
                                   roi_px=(size // 8, size // 8, 3 * size // 4, 3 * size // 4) if roi else None)
                process_frame(imgs[0], board, st)  # warm-up
                t = time.perf_counter()
                marks.append(np.mean([process_frame(im, board, st).n for im in imgs]))
                ms.append((time.perf_counter() - t) / len(imgs) * 1e3)
            count = (24 if quick else 48) if size >= 2048 else (48 if quick else 120)
            seq = _sequence(os.path.join(src, "seq"), names, count)
            fps = []
            for refine, ds, roi in variants:
                st = FrameSettings(pixel_mm=pix, bits=board.bits, refine=refine, downsample=ds,
                                   roi_px=(size // 8, size // 8, 3 * size // 4, 3 * size // 4) if roi else None)
                # steady state: from the first result on (the pool's start-up is a one-off cost)
                t_first, n_after = None, 0
                for _ in map_frames(open_frames(seq), board, st, workers=2):
                    if t_first is None:
                        t_first = time.perf_counter()
                    else:
                        n_after += 1
                fps.append(n_after / (time.perf_counter() - t_first))
            print(f"{label:<14}{size:>6}{pix * 1e3:>7.0f}{marks[0]:>6.1f}{marks[3]:>5.1f}{t_png:>7.1f}"
                  + "".join(f"{v:>7.1f}" for v in ms) + f"{fps[0]:>8.1f}" + "".join(f"{v:>7.1f}" for v in fps[1:])
                  + f"{max(fps) / 80:>14.2f}x")
        # memory: the parent's peak RSS does not grow with the sequence length
        label, board, size, pix = cases[0]
        src = os.path.join(root, f"{size}_{pix}_{board.pitch_mm}")
        names = sorted(os.path.join(src, f) for f in os.listdir(src) if f.startswith("src_"))
        from kinid.stages.contour.track import TrackBuilder

        st = FrameSettings(pixel_mm=pix, bits=board.bits, refine="centroid")
        print("\n2. memory of the parent process (resident set, MB) after streaming N frames of", f"{size}x{size}")
        for count in ((40, 160) if quick else (100, 400)):
            seq = _sequence(os.path.join(root, f"mem_{count}"), names, count)
            builder = TrackBuilder(board, st)
            for r in map_frames(open_frames(seq), board, st, workers=2):
                builder.add(r)
            builder.finish()
            print(f"   N = {count:4d}: {_rss_mb():.1f} MB")
    finally:
        shutil.rmtree(root, ignore_errors=True)


def bench_accuracy():
    """Reference mark 100+ mm from the marks in view: two-mark rotation per frame vs joint rotation."""
    from kinid.stages.contour.track import FrameResult, FrameSettings, estimate_track
    from kinid.vision.board import make_board

    board = make_board()
    rng = np.random.default_rng(3)
    print("\n3. accuracy of the reference mark 100-150 mm away from the marks in view (patent board, 48 x 48 mm"
          " field, 200 frames on a 50 mm circle)")
    print(f"{'locator noise':>14}{'two-mark (patent) RMS um':>26}{'joint (kinid) RMS um':>22}")
    angle = math.radians(0.8)
    c = complex(math.cos(angle), math.sin(angle))
    phi = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    track = np.column_stack([50 * np.cos(phi), 50 * np.sin(phi)])
    track -= track[0]
    rows, cols = np.mgrid[0:board.rows, 0:board.cols]
    b = (cols.ravel() + 1j * rows.ravel()) * board.pitch_mm
    codes = np.asarray(board.codes).ravel()
    start = complex(-104.6, -95.3)
    for noise_um in (0.1, 0.3, 1.0):
        sigma_mm = noise_um * 1e-3
        results, patent = [], []
        for d in track:
            z = c * b + start + complex(*d)
            sel = (np.abs(z.real) < 17.5) & (np.abs(z.imag) < 17.5)
            zs = z[sel] + rng.normal(0, sigma_mm, sel.sum()) + 1j * rng.normal(0, sigma_mm, sel.sum())
            bs = b[sel]
            pix = np.column_stack([zs.real, zs.imag])
            results.append(FrameResult(int(sel.sum()), (2000, 2000), tuple(int(v) for v in codes[sel]),
                                       np.column_stack([bs.real, bs.imag]), pix,
                                       pix / 0.02 + 999.5))
            # patent: the mark nearest the centre and its nearest neighbour give the rotation of this frame
            i = int(np.argmin(np.abs(zs)))
            j = int(np.argmin(np.where(np.arange(len(zs)) == i, np.inf, np.abs(bs - bs[i]))))
            rot = ((zs[j] - zs[i]) / (bs[j] - bs[i]))
            rot /= abs(rot)
            patent.append(zs[i] + rot * (b[0] - bs[i]))  # reference: mark (0, 0)
        truth0 = c * b[0] + start
        tr = estimate_track(results, board, FrameSettings(pixel_mm=1.0))
        # one rotation for the whole sequence: every mark of the rigid board has the same displacement, so
        # kinid's track (of the mark nearest the centre) is also that of mark (0, 0)
        joint = tr.xy_mm
        p = np.array(patent) - truth0
        p = np.column_stack([p.real, p.imag])
        err_p = (p - track) * 1e3
        err_p -= err_p[0]
        err_j = (joint - track) * 1e3
        print(f"{noise_um:>11.1f} um{np.sqrt(np.mean(np.sum(err_p ** 2, 1))):>26.3f}"
              f"{np.sqrt(np.mean(np.sum(err_j ** 2, 1))):>22.3f}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer cases and frames")
    a = ap.parse_args()
    bench_accuracy()
    bench_speed(a.quick)
