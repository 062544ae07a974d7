"""Benchmark: sub-pixel template matching methods side by side.

Renders textured plates (a random smooth texture; random printed discs and
bars) with known sub-pixel shifts, grey-level noise sigma = 2 and blur, and
prints for each refinement method of :func:`vision.template.locate_template`
(and OpenCV's ``phaseCorrelate`` on the whole frame) the RMS and max shift
error against truth and the time per call.

Run: ``MPLBACKEND=Agg python benchmarks/bench_template.py [n_trials]``
"""
from __future__ import annotations

import sys
import time

import numpy as np


def render_plate(coverage, shift_px, rng, *, shape=(192, 192), pixel_mm=0.05, blur_px=0.8, noise_sigma=2.0):
    """Image of a plate whose content is moved by ``shift_px`` (x right, y down)."""
    from kinid.vision.render import render_pattern

    shift = np.asarray(shift_px, dtype=float)

    def image_to_plane(pts_px):
        return (np.asarray(pts_px, dtype=float) - shift) * pixel_mm

    return render_pattern(coverage, shape, image_to_plane, supersample=4, blur_px=blur_px,
                          noise_sigma=noise_sigma, rng=rng)


def textures(rng):
    from kinid.vision.calibration_targets import printed_features_coverage, smooth_texture_coverage

    pixel_mm = 0.05
    return {
        "smooth texture": smooth_texture_coverage(rng, wavelength_mm=4 * pixel_mm, n_waves=80),
        "printed features": printed_features_coverage(rng, (0.0, 0.0, 192 * pixel_mm, 192 * pixel_mm),
                                                      n_features=90, size_mm=(0.3, 1.6)),
    }


def main(n_trials=25):
    import cv2

    from kinid.vision.template import locate_template, make_template

    rng = np.random.default_rng(20261122)
    methods = ["lk", "ecc", "upsampled", "ncc", "gauss", "phase"]
    roi = (48, 48, 96, 96)
    print(f"template {roi[2]}x{roi[3]} px in a 192x192 frame, noise sigma 2 grey levels, blur 0.8 px, "
          f"{n_trials} random shifts in [-3, 3] px")
    for name, coverage in textures(rng).items():
        ref = render_plate(coverage, (0.0, 0.0), rng)
        tmpl = make_template(ref, roi)
        shifts = rng.uniform(-3, 3, (n_trials, 2))
        images = [render_plate(coverage, s, rng) for s in shifts]
        print(f"\n{name}:")
        print(f"  {'method':<22}{'rms err px':>12}{'max err px':>12}{'bias x,y px':>20}{'ms/call':>10}{'found':>7}")
        for method in methods + ["cv2.phaseCorrelate"]:
            err = []
            start = time.perf_counter()
            for s, img in zip(shifts, images):
                if method == "cv2.phaseCorrelate":
                    window = cv2.createHanningWindow(ref.shape[::-1], cv2.CV_64F)
                    (dx, dy), _ = cv2.phaseCorrelate(ref.astype(np.float64), img.astype(np.float64), window)
                    err.append((dx - s[0], dy - s[1]))
                    continue
                m = locate_template(img, tmpl, search_px=5, method=method)
                if m.found:
                    err.append((m.dx_px - s[0], m.dy_px - s[1]))
            ms = 1000 * (time.perf_counter() - start) / n_trials
            e = np.array(err)
            rms = np.sqrt((e ** 2).sum(axis=1).mean())
            bias = e.mean(axis=0)
            print(f"  {method:<22}{rms:12.4f}{np.abs(e).max():12.4f}{bias[0]:10.4f}{bias[1]:10.4f}{ms:10.2f}"
                  f"{len(e):>4}/{n_trials}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 25)
