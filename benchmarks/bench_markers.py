"""Benchmark of the ring-coded mark detector and the circle-centre locators (prints figures).

Run: ``python benchmarks/bench_markers.py`` (about a minute).

1. Locator accuracy against noise, side by side: blurred-disk model fit, background-subtracted
   weighted centroid, plain binary centroid, ellipse fitted to a threshold contour, OpenCV's
   SimpleBlobDetector with its shape filters on (circularity, inertia, convexity). Disks drawn by OpenCV at 8x and INTER_AREA-downsampled (not the project's
   renderer), radius 8-20 px, blur 0.8 px, contrast 190 grey levels.
2. Detection + decoding time of a 2048 x 2048 frame holding 9 and 16 marks (and accuracy), beside
   SimpleBlobDetector (filters on) at threshold steps 20, 10 and 5: its configuration printed beside its figures.
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
#: (circularity, inertia, convexity), the threshold step chosen by measurement in section 2.
BLOB_FILTERS = {"minCircularity": 0.8, "minInertiaRatio": 0.6, "minConvexity": 0.9}


def blob_detector(threshold_step: float = 10.0, min_area: float = 50.0):
    p = cv2.SimpleBlobDetector_Params()
    p.filterByColor, p.blobColor = True, 0
    p.filterByArea, p.minArea, p.maxArea = True, min_area, 1e6
    p.filterByCircularity = p.filterByConvexity = p.filterByInertia = True
    for name, value in BLOB_FILTERS.items():
        setattr(p, name, value)
    p.thresholdStep = threshold_step
    return cv2.SimpleBlobDetector_create(p)


def blob_label(threshold_step) -> str:
    return ("SimpleBlobDetector(filters on: " + ", ".join(f"{k}={v}" for k, v in BLOB_FILTERS.items())
            + f", thresholdStep={threshold_step:g}, minThreshold=10, maxThreshold=220)")


def accuracy_table(rng):
    det = blob_detector()
    methods = {
        "model fit": lambda im: (lambda r: (r.x_px, r.y_px))(locate_disk(im, method="fit")),
        "weighted centroid": lambda im: (lambda r: (r.x_px, r.y_px))(locate_disk(im, method="centroid")),
        "binary centroid": binary_centroid,
        "contour ellipse": contour_ellipse,
        "SimpleBlobDetector": lambda im: max(det.detect(im), key=lambda k: k.size).pt,
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


def timing(rng):
    print("\n2. Detection + decoding of a 2048 x 2048 frame (15 runs; blur 1 px, noise 2 grey levels)")
    print(f"   machine load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores (wall time suffers under load)")
    for n_side in (3, 4):
        board = make_board(n_side, n_side)
        pix = 16.0 * n_side / 2048 / 0.92  # the marks fill the frame, every ring inside it
        half = (n_side - 1) / 2 * 16.0 / pix
        H = similarity_plane_to_image(pix, 3.0, (1023.5 - half, 1023.5 - half))
        img = render_pattern(board_coverage(board), (2048, 2048), homography_image_to_plane(H), blur_px=1.0,
                             noise_sigma=2.0, rng=rng)
        for refine in ("fit", "centroid"):
            detect_markers(img, refine=refine)
            ts, cpu = [], []
            for _ in range(15):
                t0, c0 = time.perf_counter(), time.process_time()
                ms = detect_markers(img, refine=refine)
                ts.append(time.perf_counter() - t0)
                cpu.append(time.process_time() - c0)
            err = []
            for m in ms:
                r, c = board.position_of(m.code)
                p = H @ np.array([*board.mark_mm(r, c), 1.0])
                err.append((m.x_px - p[0], m.y_px - p[1]))
            print(f"  {n_side * n_side:2d} marks (centre r {2.5 / pix:.0f} px), refine={refine:<8}: decoded "
                  f"{len(ms):2d}, wall min {1000 * min(ts):6.1f} ms (median {1000 * np.median(ts):6.1f}), "
                  f"CPU min {1000 * min(cpu):6.1f} ms, centre RMS {np.sqrt(np.mean(np.square(err))):.4f} px")
        truth = np.array([(H @ np.array([*board.mark_mm(*board.position_of(code)), 1.0]))[:2]
                          for row in board.codes for code in row])
        for step in (20.0, 10.0, 5.0):  # the peer's threshold step, chosen by measurement
            det = blob_detector(step, min_area=0.5 * np.pi * (2.5 / pix) ** 2)
            ts = []
            for _ in range(15):
                t0 = time.perf_counter()
                kps = det.detect(img)
                ts.append(time.perf_counter() - t0)
            pts = np.array([k.pt for k in kps]).reshape(-1, 2)
            err = []
            for p in truth:  # each mark's centre disk: the nearest blob within 3 px
                d = np.hypot(*(pts - p).T) if len(pts) else np.array([np.inf])
                if d.min() < 3:
                    err.append(pts[int(np.argmin(d))] - p)
            print(f"  {n_side * n_side:2d} marks, {blob_label(step)}: found {len(err):2d} centres (not decoded), "
                  f"{len(kps)} blobs, wall min {1000 * min(ts):6.1f} ms (median {1000 * np.median(ts):6.1f}), "
                  f"centre RMS {np.sqrt(np.mean(np.square(err))) if err else float('nan'):.4f} px")


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
    rng = np.random.default_rng(2026)
    accuracy_table(rng)
    timing(rng)
    render_time(rng)
    perspective_bias()
    robustness(rng)


if __name__ == "__main__":
    main()
