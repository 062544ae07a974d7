"""Ring-coded marks in large photographs: the pyramid search of ``detect_markers`` against a tiled search.

Renders 24 Mpx (6000 x 4000) photographs of boards of ring-coded marks (kinid.vision.render_photo.board_photo:
a pinhole camera looking at a tilted board, light falling off across the frame, blur, noise, JPEG at
quality 85), with centre circles of 15-60 px diameter, and runs on each

* ``detect_markers`` (the candidate search on a scale pyramid with local thresholds), and
* the peer: overlapping tiles of 1024 px (256 px overlap), each given to the earlier detector
  (one global threshold per tile, ``kinid.vision.ringcode.detect._detect_single_scale``), duplicates merged,

in one process, and prints decoded / wrong / missed and the wall time per frame of both (and, for
reference, of the earlier search on the whole frame: one global threshold on a copy shrunk to ~1024 px).

Marks counted: the whole ring in the frame and a centre circle of at least 15 px diameter. A decoded
mark lies within half a centre radius of a true one and has its code; a wrong one has another code
or is no mark at all.

With ``--photos FOLDER`` it also reads the photographs there (counter-clockwise codes, as the folder's
README says) and, for those with a ground-truth grid file (``gt_black3.txt`` for ``..._black3.png``),
prints decoded / wrong / missed, also with the photograph shrunk 0.5, 0.35 and 0.25 times into a frame
of its own size (the same targets smaller in the frame); for the others the codes found. The
photographs are only read.

Usage::

    python benchmarks/bench_photo_markers.py [--photos ../shared/real/photos] [--frames 4] [--seed 5]
"""
from __future__ import annotations

import argparse
import pathlib
import re
import sys
import time

import numpy as np

from kinid.vision.render_photo import board_photo
from kinid.vision.ringcode import detect_markers
from kinid.vision.ringcode.detect import _detect_single_scale

TILE, OVERLAP = 1024, 256


def tiled_detect(img, bits=12, clockwise=True, tile=TILE, overlap=OVERLAP):
    """The peer: overlapping tiles, each given to the earlier (single-scale) detector; duplicates merged."""
    h, w = img.shape[:2]
    step = tile - overlap

    def starts(n):
        if n <= tile:
            return [0]
        s = list(range(0, n - tile, step))
        return s + [n - tile]

    found = []
    for y0 in starts(h):
        for x0 in starts(w):
            for m in _detect_single_scale(img[y0:y0 + tile, x0:x0 + tile], bits=bits, clockwise=clockwise):
                found.append(type(m)(m.code, m.x_px + x0, m.y_px + y0, m.radius_px, m.bits))
    kept = []
    for m in found:
        if all(np.hypot(m.x_px - k.x_px, m.y_px - k.y_px) > 0.5 * k.radius_px for k in kept):
            kept.append(m)
    return kept


def score(found, truth, min_d=15.0):
    """(decoded, wrong, missed, counted, centre RMS px) of detections against the rendered truth."""
    counted = truth["inside"] & (truth["d"] >= min_d)
    ok = np.zeros(len(truth), bool)
    wrong = 0
    err = []
    for m in found:
        d = np.hypot(truth["x"] - m.x_px, truth["y"] - m.y_px)
        i = int(np.argmin(d))
        if d[i] > 0.25 * truth["d"][i]:
            wrong += 1  # not at a mark
        elif truth["code"][i] != m.code:
            wrong += 1
        else:
            ok[i] = True
            err.append(d[i])
    decoded = int(np.count_nonzero(ok & counted))
    rms = float(np.sqrt(np.mean(np.square(err)))) if err else float("nan")
    return decoded, wrong, int(np.count_nonzero(counted)) - decoded, int(np.count_nonzero(counted)), rms


def run_synthetic(args):
    rng = np.random.default_rng(args.seed)
    ranges = [(15, 24), (20, 34), (30, 46), (40, 60)][: args.frames]
    shape = (args.height, args.width)
    print(f"synthetic frames: {shape[1]} x {shape[0]} px, {len(ranges)} frames, centre-circle diameters per frame "
          f"{ranges} px, 12-bit marks (centre 5, ring 9-13 mm) on a grid of {args.pitch} ring diameters, "
          f"tilt <= 35 deg, blur {args.blur} px, noise 2 grey levels, JPEG quality 85, light 0.45-1.0, "
          f"seed {args.seed}; "
          f"time: the fastest of {args.repeat} alternate runs")
    print(f"peer: tiles of {TILE} px, overlap {OVERLAP} px, each to the single-scale detector; duplicates merged")
    header = f"{'frame':>5} {'d range':>9} {'marks':>6} | {'pyramid: decoded wrong missed  time':>36} | " \
             f"{'tiled: decoded wrong missed  time':>34}"
    print(header)
    tot = {"p": np.zeros(5), "t": np.zeros(5), "b": np.zeros(5)}
    rms = {"p": [], "t": []}
    for k, dr in enumerate(ranges):
        t0 = time.perf_counter()
        img, truth = board_photo(shape, dr, pitch=args.pitch, blur_px=args.blur, rng=rng)
        t_render = time.perf_counter() - t0
        row = []
        runs = {"p": (lambda im: detect_markers(im, bits=12)), "t": (lambda im: tiled_detect(im, 12))}
        best = {"p": np.inf, "t": np.inf}
        for _ in range(args.repeat):  # alternately, the fastest run of each
            for key, fn in runs.items():
                t0 = time.perf_counter()
                found = fn(img)
                best[key] = min(best[key], time.perf_counter() - t0)
                if key == "p":
                    found_p = found
                else:
                    found_t = found
        t0 = time.perf_counter()
        found_b = _detect_single_scale(img, bits=12)
        t_b = time.perf_counter() - t0
        dec, wr, mi, cnt, _ = score(found_b, truth)
        tot["b"] += (dec, wr, mi, cnt, t_b)
        for key, found in (("p", found_p), ("t", found_t)):
            dt = best[key]
            dec, wr, mi, cnt, r = score(found, truth)
            tot[key] += (dec, wr, mi, cnt, dt)
            rms[key].append(r)
            row.append(f"{dec:>7} {wr:>5} {mi:>6} {dt:>7.2f} s")
        counted = int(np.count_nonzero(truth["inside"] & (truth["d"] >= 15)))
        d_in = truth["d"][truth["inside"]]
        print(f"{k:>5} {d_in.min():>4.0f}-{d_in.max():<4.0f} {counted:>6} | {row[0]:>36} | {row[1]:>34}"
              f"   (render {t_render:.1f} s)")
    for key, name in (("p", "pyramid"), ("t", "tiled")):
        dec, wr, mi, cnt, dt = tot[key]
        print(f"{name:>8}: decoded {int(dec)}/{int(cnt)} ({100 * dec / max(cnt, 1):.2f} %), wrong {int(wr)}, "
              f"missed {int(mi)}, {dt / len(ranges):.2f} s per frame, centre RMS (vs ellipse centre) "
              f"{np.nanmean(rms[key]):.4f} px")
    dec, wr, mi, cnt, dt = tot["b"]
    print(f"  before: decoded {int(dec)}/{int(cnt)} ({100 * dec / max(cnt, 1):.2f} %), wrong {int(wr)}, "
          f"missed {int(mi)}, {dt / len(ranges):.2f} s per frame (the earlier search on the whole frame, one run)")
    print(f"time ratio tiled / pyramid: {tot['t'][4] / tot['p'][4]:.2f}")


def read_grid(path):
    """Ground-truth grid: rows of codes, '-' where no coded mark is."""
    rows = [line.split() for line in pathlib.Path(path).read_text().splitlines() if line.strip()]
    return [[None if v == "-" else int(v) for v in r] for r in rows]


def score_grid(found, grid):
    """(decoded, wrong, missed, marks) of detections against a grid of codes (positions from a fitted homography)."""
    import cv2

    cells = {(r, c): v for r, row in enumerate(grid) for c, v in enumerate(row) if v is not None}
    where = {}
    for (r, c), v in cells.items():
        where.setdefault(v, []).append((r, c))
    unique = [(m, where[m.code][0]) for m in found if len(where.get(m.code, [])) == 1]
    total = len(cells)
    if len(unique) >= 4:
        src = np.array([[c, r] for _, (r, c) in unique], np.float32)
        dst = np.array([[m.x_px, m.y_px] for m, _ in unique], np.float32)
        H, _ = cv2.findHomography(src, dst, cv2.RANSAC, 0.25 * float(np.median(
            [np.hypot(*(dst[i] - dst[j])) / max(np.hypot(*(src[i] - src[j])), 1e-9)
             for i in range(len(src)) for j in range(i + 1, min(len(src), i + 4))])))
    else:
        H = None
    ok, wrong = set(), 0
    for m in found:
        if H is not None:
            g = np.linalg.solve(H, [m.x_px, m.y_px, 1.0])
            cell = (int(round(g[1] / g[2])), int(round(g[0] / g[2])))
        else:  # too few to place: judge by the code only
            cell = where.get(m.code, [None])[0]
        if cell in cells and cells[cell] == m.code and cell not in ok:
            ok.add(cell)
        else:
            wrong += 1
    return len(ok), wrong, total - len(ok), total


#: Factors by which the photographs with a ground truth are also shrunk (into a frame of their own size).
SHRINK = (0.5, 0.35, 0.25)


def shrunk(img, f):
    """``img`` shrunk by ``f`` (area averaging) in the middle of a frame of its size, filled with its median."""
    import cv2

    h, w = img.shape
    small = cv2.resize(img, (int(round(w * f)), int(round(h * f))), interpolation=cv2.INTER_AREA)
    out = np.full_like(img, int(np.median(small)))
    y0, x0 = (h - small.shape[0]) // 2, (w - small.shape[1]) // 2
    out[y0:y0 + small.shape[0], x0:x0 + small.shape[1]] = small
    return out


def run_photos(folder):
    import cv2

    folder = pathlib.Path(folder)
    if not folder.is_dir():
        print(f"photos: {folder} is not a folder", file=sys.stderr)
        return
    print(f"\nphotos in {folder} (codes read counter-clockwise, as that project reads them):")
    for path in sorted(folder.iterdir()):
        if path.suffix.lower() not in (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff"):
            continue
        img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if img is None:
            print(f"  {path.name}: cannot read")
            continue
        mb = re.search(r"bit(\d+)", path.name)
        bits = int(mb.group(1)) if mb else 12
        mg = re.search(r"(black|white)(\d+)", path.name)
        gt = folder / f"gt_{mg.group(1)}{mg.group(2)}.txt" if mg else None
        grid = read_grid(gt) if gt is not None and gt.is_file() else None
        print(f"  {path.name}: {img.shape[1]} x {img.shape[0]} px, {bits} bits, "
              f"ground truth {gt.name if grid else 'none'}")
        views = [(1.0, img)]
        if grid is not None and max(img.shape) >= 2048:
            # the same scene from farther away: the photo shrunk, in the middle of a frame of the same size
            for f in SHRINK:
                views.append((f, shrunk(img, f)))
        for f, view in views:
            if f != 1.0:
                print(f"   shrunk {f:g} x into the same {img.shape[1]} x {img.shape[0]} frame:")
            for name, fn in (("pyramid", lambda im: detect_markers(im, bits=bits, clockwise=False)),
                             ("tiled", lambda im: tiled_detect(im, bits, clockwise=False)),
                             ("before", lambda im: _detect_single_scale(im, bits=bits, clockwise=False))):
                t0 = time.perf_counter()
                found = fn(view)
                dt = time.perf_counter() - t0
                radii = [m.radius_px for m in found]
                size = f"centre radius {min(radii):.1f}-{max(radii):.1f} px, " if found else ""
                if grid is not None:
                    dec, wr, mi, tot = score_grid(found, grid)
                    print(f"    {name:>8}: decoded {dec}/{tot}, wrong {wr}, missed {mi}, {size}{dt:.2f} s")
                else:
                    print(f"    {name:>8}: {len(found)} decoded, codes {sorted(m.code for m in found)}, {size}"
                          f"{dt:.2f} s")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photos", help="folder of real photographs with gt_*.txt grid files (only read)")
    ap.add_argument("--frames", type=int, default=4, help="synthetic frames (1-4), default 4")
    ap.add_argument("--width", type=int, default=6000)
    ap.add_argument("--height", type=int, default=4000)
    ap.add_argument("--pitch", type=float, default=3.0, help="grid pitch in ring diameters, default 3")
    ap.add_argument("--blur", type=float, default=1.0, help="Gaussian blur, px, default 1")
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--repeat", type=int, default=2, help="runs of each detector per frame (alternately; "
                    "the fastest is printed), default 2")
    ap.add_argument("--no-synthetic", action="store_true", help="only the photographs")
    args = ap.parse_args(argv)
    import cv2

    print(f"kinid bench_photo_markers; OpenCV {cv2.__version__}, {cv2.getNumThreads()} threads")
    if not args.no_synthetic:
        run_synthetic(args)
    if args.photos:
        run_photos(args.photos)


if __name__ == "__main__":
    main()
