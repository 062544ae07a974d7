"""Benchmark of the ring-coded mark detector and the circle-centre locators (prints figures).

Run: ``python benchmarks/bench_markers.py`` (a few minutes; ``--timing``: section 2 alone, about 2 minutes).

1. Locator accuracy against noise, side by side: blurred-disk model fit, background-subtracted
   weighted centroid, plain binary centroid, ellipse fitted to a threshold contour, OpenCV's
   SimpleBlobDetector with its shape filters on (circularity, inertia, convexity). Disks drawn by OpenCV at 8x and INTER_AREA-downsampled (not the project's
   renderer), radius 8-20 px, blur 0.8 px, contrast 190 grey levels.
2. Detection + decoding time of a 2048 x 2048 frame holding 16 and 196 marks (and accuracy), beside
   SimpleBlobDetector (filters on) at each of BLOB_SETTINGS (threshold step and band, repeatability),
   each printed with its CPU time and accuracy; the peer is the fastest at kinid's accuracy or better.
   One process, one thread (threadpoolctl, cv2.setNumThreads), interleaved repeats, CPU time.
3. Render time of a 1024 x 1024 board frame.
4. Perspective bias of circle centres (ellipse centre vs projected centre).
5. Decoding robustness on marks drawn by OpenCV (pie slices at 8x, INTER_AREA; not the
   project's renderer): random codes, rotations, polarities, sizes, blur, noise; tilted
   views; rings cut by the image border.
"""
from __future__ import annotations

import os
import time

import cv2
import numpy as np

from kinid.vision.board import make_board
from kinid.vision.circles import locate_disk
from kinid.vision.render import board_coverage, homography_image_to_plane, render_pattern, similarity_plane_to_image
from kinid.vision.ringcode import canonical_code, detect_markers

UP, SHIFT = 8, 4


def draw_disk(shape, c, r, blur, noise, rng):
    h, w = shape
    canvas = np.full((h * UP, w * UP), 220, np.uint8)
    cc = tuple(int(round(((v + 0.5) * UP - 0.5) * 2 ** SHIFT)) for v in c)
    cv2.circle(canvas, cc, int(round(r * UP * 2 ** SHIFT)), 30, -1, cv2.LINE_AA, SHIFT)
    img = cv2.resize(canvas.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA)
    img = cv2.GaussianBlur(img, (0, 0), blur) + rng.normal(0, noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def binary_centroid(img):
    m = (img < 125).astype(np.uint8)
    n, lab, st, cen = cv2.connectedComponentsWithStats(m)
    k = 1 + int(np.argmax(st[1:, cv2.CC_STAT_AREA]))
    return cen[k]


def contour_ellipse(img):
    m = (img < 125).astype(np.uint8)
    cs, _ = cv2.findContours(m, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    c = max(cs, key=cv2.contourArea)
    (x, y), _, _ = cv2.fitEllipse(c)
    return x, y


#: SimpleBlobDetector as its best user would set it for round dark marks: its shape filters on
#: (circularity, inertia, convexity) and by area; the thresholds and the repeatability vary in section 2.
BLOB_FILTERS = {"minCircularity": 0.8, "minInertiaRatio": 0.6, "minConvexity": 0.9}

#: The detector's settings tried in section 2: (thresholdStep, minThreshold, maxThreshold, minRepeatability).
#: OpenCV's defaults are (10, 50, 220, 2); a narrower band of thresholds around the mid-grey of the marks
#: is faster (fewer binarisations), a finer step averages more contours.
BLOB_SETTINGS = ([(step, lo, hi, rep) for lo, hi in ((10, 220), (50, 220), (70, 180), (100, 150))
                  for step in (5, 10, 20) for rep in (1, 2) if (hi - lo) / step >= rep]
                 + [(step, 10, 220, 2) for step in (4, 3, 2.5)] + [(2.5, 50, 220, 2)])  # finer: more accurate, slower


def blob_detector(threshold_step=10.0, min_threshold=10.0, max_threshold=220.0, min_repeatability=2,
                  min_area=50.0):
    p = cv2.SimpleBlobDetector_Params()
    p.filterByColor, p.blobColor = True, 0
    p.filterByArea, p.minArea, p.maxArea = True, min_area, 1e6
    p.filterByCircularity = p.filterByConvexity = p.filterByInertia = True
    for name, value in BLOB_FILTERS.items():
        setattr(p, name, value)
    p.thresholdStep, p.minThreshold, p.maxThreshold = threshold_step, min_threshold, max_threshold
    p.minRepeatability = min_repeatability
    return cv2.SimpleBlobDetector_create(p)


def blob_label(step, lo, hi, rep) -> str:
    return f"thresholdStep={step:g}, minThreshold={lo:g}, maxThreshold={hi:g}, minRepeatability={rep}"


def accuracy_table(rng):
    det = blob_detector(10, 50, 220, 2)
    methods = {
        "model fit": lambda im: (lambda r: (r.x_px, r.y_px))(locate_disk(im, method="fit")),
        "weighted centroid": lambda im: (lambda r: (r.x_px, r.y_px))(locate_disk(im, method="centroid")),
        "binary centroid": binary_centroid,
        "contour ellipse": contour_ellipse,
        "SimpleBlobDetector": lambda im: max(det.detect(im), key=lambda k: k.size).pt,  # OpenCV defaults
    }
    sigmas = [0.0, 1.0, 2.0, 4.0, 8.0]
    print("\n1. Centre RMS error (px) vs noise sigma (grey levels), 40 disks each, r 8-20 px, blur 0.8 px")
    print(f"{'method':<20}" + "".join(f"{'s=' + format(s, 'g'):>10}" for s in sigmas) + f"{'ms/call':>10}")
    cases = []
    for s in sigmas:
        for _ in range(40):
            c = (50 + rng.uniform(-2, 2), 50 + rng.uniform(-2, 2))
            cases.append((s, c, draw_disk((100, 100), c, rng.uniform(8, 20), 0.8, s, rng)))
    for name, f in methods.items():
        row, t_total = [], 0.0
        for s in sigmas:
            err = []
            for s2, c, img in cases:
                if s2 != s:
                    continue
                t0 = time.perf_counter()
                x, y = f(img)
                t_total += time.perf_counter() - t0
                err.append((x - c[0], y - c[1]))
            row.append(float(np.sqrt(np.mean(np.square(err)))))
        print(f"{name:<20}" + "".join(f"{v:>10.4f}" for v in row) + f"{1000 * t_total / len(cases):>10.2f}")


def _centre_rms(pts, truth, tol_px=3.0):
    """Number of true centres with a point within ``tol_px`` and the RMS error of those points (px)."""
    pts = np.asarray(pts, float).reshape(-1, 2)
    err = []
    for p in truth:
        d = np.hypot(*(pts - p).T) if len(pts) else np.array([np.inf])
        if d.min() < tol_px:
            err.append(pts[int(np.argmin(d))] - p)
    return len(err), (float(np.sqrt(np.mean(np.square(err)))) if err else float("nan"))


def timing(rng, repeats=7):
    """kinid's detect_markers beside SimpleBlobDetector at each setting of BLOB_SETTINGS: one process,
    one BLAS and one OpenCV thread, the methods interleaved in every repeat, CPU time (minimum and median)."""
    from threadpoolctl import threadpool_limits

    cv2.setNumThreads(1)
    print(f"\n2. Detection + decoding of a 2048 x 2048 frame ({repeats} interleaved repeats, CPU time, one thread;"
          " blur 1 px, noise 2 grey levels)")
    print(f"   machine load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    for n_side in (4, 14):
        board = make_board(n_side, n_side)
        pix = 16.0 * n_side / 2048 / 0.92  # the marks fill the frame, every ring inside it
        half = (n_side - 1) / 2 * 16.0 / pix
        H = similarity_plane_to_image(pix, 3.0, (1023.5 - half, 1023.5 - half))
        img = render_pattern(board_coverage(board), (2048, 2048), homography_image_to_plane(H), blur_px=1.0,
                             noise_sigma=2.0, rng=rng)
        truth = np.array([(H @ np.array([*board.mark_mm(*board.position_of(code)), 1.0]))[:2]
                          for row in board.codes for code in row])
        min_area = 0.5 * np.pi * (2.5 / pix) ** 2
        runs = {"kinid": lambda: [(m.x_px, m.y_px) for m in detect_markers(img)]}
        for st in BLOB_SETTINGS:
            det = blob_detector(*st, min_area=min_area)
            runs[st] = lambda det=det: [k.pt for k in det.detect(img)]
        cpu = {k: [] for k in runs}
        found = {}
        with threadpool_limits(1):
            for k, f in runs.items():  # a first call of each, untimed (caches, imports)
                found[k] = f()
            for _ in range(repeats):
                for k, f in runs.items():
                    c0 = time.process_time()
                    f()
                    cpu[k].append(time.process_time() - c0)
        n_mk = n_side * n_side
        acc = {k: _centre_rms(v, truth) for k, v in found.items()}
        ms = {k: (1000 * min(v), 1000 * np.median(v)) for k, v in cpu.items()}
        kin_n, kin_rms = acc["kinid"]
        print(f"  {n_mk} marks (centre radius {2.5 / pix:.0f} px): kinid detect_markers (find, decode, refine by "
              f"the model fit): {kin_n} of {n_mk} decoded, CPU min {ms['kinid'][0]:.1f} ms (median "
              f"{ms['kinid'][1]:.1f}), centre RMS {kin_rms:.5f} px")
        print("    SimpleBlobDetector (filters on: " + ", ".join(f"{k}={v}" for k, v in BLOB_FILTERS.items())
              + f", minArea={min_area:.0f}; finds centres, does not decode):")
        for st in BLOB_SETTINGS:
            n, rms = acc[st]
            print(f"    {blob_label(*st):<78} found {n:3d}, CPU min {ms[st][0]:7.1f} ms (median {ms[st][1]:7.1f}),"
                  f" RMS {rms:.5f} px")
        complete = [st for st in BLOB_SETTINGS if acc[st][0] == n_mk]
        equal = [st for st in complete if acc[st][1] <= kin_rms]
        if equal:
            peer = min(equal, key=lambda st: ms[st][0])
            how = "the fastest setting at kinid's accuracy or better"
        else:
            peer = min(complete or BLOB_SETTINGS, key=lambda st: acc[st][1])
            how = "no setting reaches kinid's accuracy: the most accurate one"
        print(f"    peer ({how}): {blob_label(*peer)}, {ms[peer][0]:.1f} ms, {acc[peer][1]:.5f} px -> kinid "
              f"{ms[peer][0] / ms['kinid'][0]:.2f}x its speed (by the minimum; "
              f"{ms[peer][1] / ms['kinid'][1]:.2f}x by the median)")


def render_time(rng):
    board = make_board()
    H = similarity_plane_to_image(0.06, 3.0, (50.0, 40.0))
    ts = []
    for _ in range(3):
        t0 = time.perf_counter()
        render_pattern(board_coverage(board), (1024, 1024), homography_image_to_plane(H), blur_px=0.8,
                       noise_sigma=2.0, rng=rng)
        ts.append(time.perf_counter() - t0)
    print(f"\n3. Render of a 1024 x 1024 board frame (0.06 mm/px, supersample 4): min {1000 * min(ts):.0f} ms")


def _ellipse_centre(H, c, r):
    C = np.array([[1, 0, -c[0]], [0, 1, -c[1]], [-c[0], -c[1], c[0] ** 2 + c[1] ** 2 - r * r]])
    Hi = np.linalg.inv(H)
    Cp = Hi.T @ C @ Hi
    return np.linalg.solve(Cp[:2, :2], -Cp[:2, 2])


def perspective_bias():
    print("\n4. Perspective bias |ellipse centre - projected centre| (px): pinhole f = 4000 px, plane at 200 mm")
    print("   (20 px/mm at the axis), board tilted about its x axis; mark on the axis and 40 mm off it")
    print(f"{'tilt':>6} {'offset':>8} {'centre d5':>10} {'ring d9':>10} {'ring d13':>10}")
    f, Z = 4000.0, 200.0
    K = np.array([[f, 0, 2047.5], [0, f, 2047.5], [0, 0, 1.0]])
    for tilt in (0.0, 2.0, 5.0, 10.0, 20.0):
        a = np.deg2rad(tilt)
        R = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
        H = K @ np.column_stack([R[:, 0], R[:, 1], [0, 0, Z]])
        for off in (0.0, 40.0):
            c = (off, off)
            p = H @ np.array([c[0], c[1], 1.0])
            p = p[:2] / p[2]
            vals = [np.hypot(*(_ellipse_centre(H, c, d / 2) - p)) for d in (5.0, 9.0, 13.0)]
            print(f"{tilt:>5.0f}° {off:>6.0f}mm" + "".join(f"{v:>10.4f}" for v in vals))


def draw_mark(shape, c, code, r, *, angle_deg, low, high, blur, noise, rng, H=None, bits=12):
    """Ring-coded mark drawn with OpenCV at 8x (ring 1.8-2.6 centre radii), optional warp H, INTER_AREA."""
    h, w = shape
    canvas = np.full((h * UP, w * UP), high, np.uint8)
    cc = tuple(int(round(((v + 0.5) * UP - 0.5) * 2 ** SHIFT)) for v in c)
    rc, ri, ro = (int(round(f * r * UP * 2 ** SHIFT)) for f in (1.0, 1.8, 2.6))
    step = 360.0 / bits
    for k in range(bits):
        if (code >> (bits - 1 - k)) & 1:
            cv2.ellipse(canvas, cc, (ro, ro), 0, angle_deg + k * step, angle_deg + (k + 1) * step, int(low), -1,
                        cv2.LINE_AA, SHIFT)
    cv2.circle(canvas, cc, ri, int(high), -1, cv2.LINE_AA, SHIFT)
    cv2.circle(canvas, cc, rc, int(low), -1, cv2.LINE_AA, SHIFT)
    img = canvas.astype(np.float32)
    if H is not None:
        S = np.array([[UP, 0, (UP - 1) / 2], [0, UP, (UP - 1) / 2], [0, 0, 1.0]])
        img = cv2.warpPerspective(img, S @ H @ np.linalg.inv(S), (w * UP, h * UP), flags=cv2.INTER_LINEAR,
                                  borderValue=float(high))
    img = cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)
    img = cv2.GaussianBlur(img, (0, 0), blur) + rng.normal(0, noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def robustness(rng):
    classes = sorted({canonical_code(v) for v in range(1, 4095)})
    print("\n5. Decoding on independently drawn marks (all 350 decodable classes, random rotation/polarity)")
    print(f"{'case':<46}{'marks':>6}{'decoded':>8}{'wrong':>6}{'RMS px':>9}")

    def run(name, count, make):
        dec = wrong = 0
        err = []
        for _ in range(count):
            code = int(rng.choice(classes))
            img, truth = make(code)
            found = detect_markers(img)
            if any(m.code != code for m in found):
                wrong += 1
                continue
            dec += len(found)
            if found and truth is not None:
                err.append((found[0].x_px - truth[0], found[0].y_px - truth[1]))
        rms = f"{np.sqrt(np.mean(np.square(err))):.4f}" if err else "-"
        print(f"{name:<46}{count:>6}{dec:>8}{wrong:>6}{rms:>9}")

    def plain(code):
        r = rng.uniform(6, 30)
        size = int(2 * 2.6 * r + 30 + rng.uniform(0, 40))
        c = (size / 2 + rng.uniform(-5, 5), size / 2 + rng.uniform(-5, 5))
        lo, hi = (30, 220) if rng.integers(2) else (220, 30)
        return draw_mark((size, size), c, code, r, angle_deg=rng.uniform(0, 360), low=lo, high=hi,
                         blur=rng.uniform(0.5, 1.5), noise=rng.uniform(0, 4), rng=rng), c

    def tilted(code):
        r = rng.uniform(8, 25)
        size = int(2 * 2.6 * r * 1.3 + 30)
        c = (size / 2, size / 2)
        T = np.array([[1, 0, -c[0]], [0, 1, -c[1]], [0, 0, 1.0]])
        th, k = rng.uniform(0, 2 * np.pi), rng.uniform(0, 0.35) / size
        A = np.array([[1 + rng.uniform(-.1, .1), rng.uniform(-.1, .1), 0],
                      [rng.uniform(-.1, .1), 1 + rng.uniform(-.1, .1), 0], [k * np.cos(th), k * np.sin(th), 1]])
        H = np.linalg.inv(T) @ A @ T
        lo, hi = (30, 220) if rng.integers(2) else (220, 30)
        img = draw_mark((size, size), c, code, r, angle_deg=rng.uniform(0, 360), low=lo, high=hi,
                        blur=rng.uniform(0.5, 1.0), noise=2.0, rng=rng, H=H)
        C = np.array([[1, 0, -c[0]], [0, 1, -c[1]], [-c[0], -c[1], c[0] ** 2 + c[1] ** 2 - r * r]])
        Hi = np.linalg.inv(H)
        Cp = Hi.T @ C @ Hi
        return img, np.linalg.solve(Cp[:2, :2], -Cp[:2, 2])  # centre of the imaged ellipse

    def cut(code):
        r = rng.uniform(6, 25)
        size = int(2 * 2.6 * r + 40)
        c = [size / 2, size / 2]
        d = rng.uniform(0.2, 2.5) * r
        side = int(rng.integers(4))
        c[side % 2] = d if side < 2 else size - 1 - d
        lo, hi = (30, 220) if rng.integers(2) else (220, 30)
        return draw_mark((size, size), c, code, r, angle_deg=rng.uniform(0, 360), low=lo, high=hi,
                         blur=rng.uniform(0.5, 1.2), noise=rng.uniform(0, 3), rng=rng), None

    run("r 6-30 px, blur 0.5-1.5 px, noise 0-4", 400, plain)
    run("tilted (up to 35 % scale change), noise 2", 150, tilted)
    run("ring cut by the border (expect 0 decoded)", 300, cut)


def main():
    import sys

    rng = np.random.default_rng(2026)
    if "--timing" in sys.argv[1:]:  # section 2 alone
        timing(rng)
        return
    accuracy_table(rng)
    timing(rng)
    render_time(rng)
    perspective_bias()
    robustness(rng)


if __name__ == "__main__":
    main()
