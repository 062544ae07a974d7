"""Rendered photographs of ring-coded boards: a pinhole view of a tilted board with uneven light, blur,
noise and JPEG compression, and where each mark truly is (the benchmark and tests of the marker search)."""
from __future__ import annotations

import numpy as np

from .render import _check_shape, homography_image_to_plane, render_pattern, ring_mark_coverage

__all__ = ["imaged_circle", "photo_homography", "render_marks_photo", "board_photo"]


def imaged_circle(H_plane_to_image, centre_mm, radius_mm):
    """Centre and size of the image of a plane circle under a homography (exactly, from the conic).

    Returns
    -------
    tuple of float
        ``(x_px, y_px, diameter_px)``: the centre of the image ellipse (not the image of the
        circle's centre, see docs/vision_markers.md) and twice the geometric mean of its semi-axes.
    """
    H = np.asarray(H_plane_to_image, float)
    cx, cy = (float(v) for v in centre_mm)
    r = float(radius_mm)
    C = np.array([[1.0, 0.0, -cx], [0.0, 1.0, -cy], [-cx, -cy, cx * cx + cy * cy - r * r]])
    Hi = np.linalg.inv(H)
    Cp = Hi.T @ C @ Hi
    A, b, c = Cp[:2, :2], Cp[:2, 2], Cp[2, 2]
    x0 = np.linalg.solve(A, -b)
    k = float(b @ np.linalg.solve(A, b) - c)
    ab = abs(k) / np.sqrt(abs(np.linalg.det(A)))
    return float(x0[0]), float(x0[1]), float(2.0 * np.sqrt(ab))


def _local_scale(H, xy_mm):
    """sqrt(|det J|) of the plane -> image map at plane points (N, 2): pixels per mm."""
    X, Y = xy_mm[:, 0], xy_mm[:, 1]
    u = H[0, 0] * X + H[0, 1] * Y + H[0, 2]
    v = H[1, 0] * X + H[1, 1] * Y + H[1, 2]
    w = H[2, 0] * X + H[2, 1] * Y + H[2, 2]
    ux, uy = (H[0, 0] * w - u * H[2, 0]) / w ** 2, (H[0, 1] * w - u * H[2, 1]) / w ** 2
    vx, vy = (H[1, 0] * w - v * H[2, 0]) / w ** 2, (H[1, 1] * w - v * H[2, 1]) / w ** 2
    return np.sqrt(np.abs(ux * vy - uy * vx))


def photo_homography(image_shape, d_range_px, *, center_d_mm=5.0, tilt_deg=None, max_tilt_deg=35.0,
                     focal_px=None, rng=None):
    """Plane mm -> pixel homography of a pinhole camera looking at a tilted board.

    The board plane meets the optical axis at its origin, is tilted by ``tilt_deg`` about a random
    axis and turned by a random angle in itself. Unless ``tilt_deg`` is given, the tilt is chosen
    (at most ``max_tilt_deg``) so that, over the whole frame, centre circles of ``center_d_mm`` image
    with diameters from ``d_range_px[0]`` to ``d_range_px[1]`` (the distance sets the smallest one;
    a range wider than the largest tilt gives is narrowed).

    Returns
    -------
    numpy.ndarray
        3 x 3 homography, plane mm -> pixels.
    """
    h, w = _check_shape(image_shape)
    rng = np.random.default_rng() if rng is None else rng
    d_lo, d_hi = (float(v) for v in d_range_px)
    f = float(focal_px) if focal_px else float(max(h, w))
    K = np.array([[f, 0.0, (w - 1) / 2], [0.0, f, (h - 1) / 2], [0.0, 0.0, 1.0]])
    phi, gamma = rng.uniform(0, 2 * np.pi), rng.uniform(0, 2 * np.pi)

    def rot_z(a):
        c, s = np.cos(a), np.sin(a)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def H_of(theta, Z):
        c, s = np.cos(theta), np.sin(theta)
        Rx = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
        R = rot_z(phi) @ Rx @ rot_z(-phi) @ rot_z(gamma)
        return K @ np.column_stack([R[:, 0], R[:, 1], [0.0, 0.0, Z]])

    gy, gx = np.mgrid[0:h:h / 16, 0:w:w / 24]
    grid = np.column_stack([gx.ravel(), gy.ravel()])
    grid = np.vstack([grid, [[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]]])

    def diameters(theta, Z=1000.0):
        H = H_of(theta, Z)
        mm = homography_image_to_plane(H)(grid)
        return center_d_mm * _local_scale(H, mm)

    def ratio(theta):
        d = diameters(theta)
        return d.max() / d.min()

    if tilt_deg is None:
        a, b = 0.0, np.deg2rad(max_tilt_deg)
        if ratio(b) <= d_hi / d_lo:
            theta = b
        else:
            for _ in range(40):
                m = 0.5 * (a + b)
                a, b = (m, b) if ratio(m) < d_hi / d_lo else (a, m)
            theta = 0.5 * (a + b)
    else:
        theta = np.deg2rad(float(tilt_deg))
    Z = 1000.0 * diameters(theta).min() / d_lo  # diameters scale as 1 / Z
    return H_of(theta, Z)


def render_marks_photo(image_shape, H_plane_to_image, marks, *, bits=12, center_d_mm=5.0, ring_inner_d_mm=9.0,
                       ring_outer_d_mm=13.0, paper_mm=None, paper=0.85, ink=0.08, surround=0.3, light=None,
                       blur_px=1.0, noise_sigma=2.0, jpeg_quality=85, supersample=4, rng=None) -> np.ndarray:
    """A photograph of ring-coded marks on a plane: perspective, uneven light, blur, noise and JPEG.

    Each mark is rendered exactly through the homography (anti-aliased, :func:`render_pattern` on its
    own bounding box), so large frames (24 Mpx) take seconds, not minutes.

    Parameters
    ----------
    image_shape : tuple of int
        (height, width), pixels.
    H_plane_to_image : array_like, shape (3, 3)
        Plane mm -> pixels.
    marks : sequence
        ``(x_mm, y_mm, code_bits, angle_deg)`` per mark, as in :func:`ring_mark_coverage`.
    bits, center_d_mm, ring_inner_d_mm, ring_outer_d_mm
        Ring elements and mark geometry (the monocular contour method's by default).
    paper_mm : tuple of float or None
        ``(x0, y0, x1, y1)``: the sheet the marks are printed on (reflectance ``paper``); outside it
        the surface has reflectance ``surround``. None: paper everywhere.
    paper, ink, surround : float
        Reflectances (0..1).
    light : array_like or None
        Illumination, a 2-D array of any size (resized smoothly to the image; 1 = full light, 255
        grey levels on a reflectance of 1). None: uniform.
    blur_px, noise_sigma : float
        Gaussian blur (pixels) and additive noise (grey levels), as in :func:`render_pattern`.
    jpeg_quality : int or None
        JPEG compression at this quality (OpenCV's encoder), None: none.
    supersample : int
        Sub-samples per pixel side at edges.
    rng : numpy.random.Generator or None
        Noise generator.

    Returns
    -------
    numpy.ndarray
        uint8 image.
    """
    import cv2

    h, w = _check_shape(image_shape)
    H = np.asarray(H_plane_to_image, float)
    rng = np.random.default_rng() if rng is None else rng
    to_plane = homography_image_to_plane(H)
    cov = np.zeros((h, w), np.uint8)
    ro = float(ring_outer_d_mm) / 2
    circ = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    for x_mm, y_mm, code, angle in marks:
        pts = np.column_stack([x_mm + 1.05 * ro * np.cos(circ), y_mm + 1.05 * ro * np.sin(circ), np.ones_like(circ)])
        q = pts @ H.T
        if np.any(q[:, 2] <= 0):
            continue
        px, py = q[:, 0] / q[:, 2], q[:, 1] / q[:, 2]
        x0, x1 = max(0, int(np.floor(px.min())) - 2), min(w, int(np.ceil(px.max())) + 3)
        y0, y1 = max(0, int(np.floor(py.min())) - 2), min(h, int(np.ceil(py.max())) + 3)
        if x1 <= x0 or y1 <= y0:
            continue
        cover = ring_mark_coverage((x_mm, y_mm), int(code), bits, center_d_mm, ring_inner_d_mm, ring_outer_d_mm, angle)
        off = np.array([x0, y0], float)
        patch = render_pattern(cover, (y1 - y0, x1 - x0), lambda xy, off=off: to_plane(xy + off), low=255, high=0,
                               supersample=supersample)
        np.maximum(cov[y0:y1, x0:x1], patch, out=cov[y0:y1, x0:x1])
    if paper_mm is None:
        base = np.full((h, w), float(paper), np.float32)
    else:
        a, b, c, d = (float(v) for v in paper_mm)
        corners = np.array([[a, b, 1], [c, b, 1], [c, d, 1], [a, d, 1]]) @ H.T
        poly = np.rint(corners[:, :2] / corners[:, 2:] * 16).astype(np.int32)
        sheet = np.zeros((h, w), np.uint8)
        cv2.fillPoly(sheet, [poly], 255, cv2.LINE_AA, 4)
        base = float(surround) + (float(paper) - float(surround)) * (sheet.astype(np.float32) / 255)
    refl = base - (base - float(ink)) * (cov.astype(np.float32) / 255)
    del cov, base
    if light is not None:
        L = np.asarray(light, np.float32)
        refl *= cv2.resize(L, (w, h), interpolation=cv2.INTER_CUBIC)
    img = refl * 255.0
    del refl
    if blur_px and blur_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), float(blur_px), borderType=cv2.BORDER_REPLICATE)
    if noise_sigma and noise_sigma > 0:
        img += rng.normal(0.0, float(noise_sigma), img.shape).astype(np.float32)
    out = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    if jpeg_quality is not None:
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)])
        out = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
    return out


def board_photo(image_shape, d_range_px, *, bits=12, pitch=3.0, blur_px=1.0, noise_sigma=2.0, jpeg_quality=85,
                light_range=(0.45, 1.0), max_tilt_deg=35.0, mirror=False, sheet=True, rng=None):
    """A synthetic photograph of a board of ring-coded marks, and where each mark is.

    Marks of the monocular contour method (centre Ø5, ring Ø9-Ø13 mm) on a grid of ``pitch`` ring
    diameters, random codes (all decodable rotation classes of ``bits`` bits) printed at random
    rotations, seen by :func:`photo_homography` so that centre circles image at ``d_range_px``
    diameters; light falling off across the frame (a ramp in a random direction and vignetting,
    within ``light_range``), blur, noise and JPEG (:func:`render_marks_photo`). With ``sheet`` the
    board is a sheet covering part of the view, the rest a darker surface. ``mirror=True`` flips
    the photograph left-right (a board read through a mirror, or printed mirrored): its rings read
    counter-clockwise give the printed codes.

    Returns
    -------
    tuple
        ``(image, truth)``: uint8 image and a structured array with fields ``x``, ``y`` (centre of the
        centre circle's image ellipse, pixels), ``d`` (its diameter, pixels), ``code`` (the printed
        canonical code, read clockwise on the unmirrored board), ``inside`` (the whole ring, with
        a pixel to spare, lies in the frame).
    """
    h, w = _check_shape(image_shape)
    rng = np.random.default_rng() if rng is None else rng
    n = int(bits)
    H = photo_homography((h, w), d_range_px, max_tilt_deg=max_tilt_deg, rng=rng)
    corners = homography_image_to_plane(H)(np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], float))
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    step = float(pitch) * 13.0
    if sheet:  # a sheet over 70-100 % of the view's extent in each direction
        span = hi - lo
        frac = rng.uniform(0.7, 1.0, 2)
        a = lo + rng.uniform(0, 1, 2) * (1 - frac) * span
        lo, hi = a, a + frac * span
    xs = np.arange(np.ceil(lo[0] / step) + 0.5, np.floor(hi[0] / step) - 0.4) * step
    ys = np.arange(np.ceil(lo[1] / step) + 0.5, np.floor(hi[1] / step) - 0.4) * step
    gx, gy = np.meshgrid(xs, ys)
    from .ringcode import canonical_code

    classes = np.array(sorted({canonical_code(v, n) for v in range(1, (1 << n) - 1)}))
    codes = rng.choice(classes, gx.size)
    angles = rng.uniform(0, 360, gx.size)
    marks = list(zip(gx.ravel(), gy.ravel(), codes, angles))
    # light: a ramp in a random direction times vignetting, scaled into light_range
    yy, xx = np.mgrid[0:32, 0:48]
    u, v = (xx - 23.5) / 23.5, (yy - 15.5) / 23.5
    t = rng.uniform(0, 2 * np.pi)
    field = (1 + 0.5 * (np.cos(t) * u + np.sin(t) * v)) * (1 - 0.3 * (u * u + v * v))
    field = (field - field.min()) / (field.max() - field.min())
    light = light_range[0] + (light_range[1] - light_range[0]) * field
    paper_mm = (lo[0], lo[1], hi[0], hi[1]) if sheet else None
    img = render_marks_photo((h, w), H, marks, bits=n, paper_mm=paper_mm, light=light, blur_px=blur_px,
                             noise_sigma=noise_sigma, jpeg_quality=jpeg_quality, rng=rng)
    truth = np.zeros(len(marks), dtype=[("x", float), ("y", float), ("d", float), ("code", int), ("inside", bool)])
    margin = 1.0 + 2.0 * blur_px
    for i, (x_mm, y_mm, code, _) in enumerate(marks):
        x, y, d = imaged_circle(H, (x_mm, y_mm), 2.5)
        ring_d = imaged_circle(H, (x_mm, y_mm), 6.5)[2]
        if mirror:
            x = w - 1 - x
        r_out = 0.5 * ring_d * 1.15  # the ring's image ellipse is not round: allow for its long axis
        truth[i] = (x, y, d, int(code), r_out + margin <= x <= w - 1 - r_out - margin
                    and r_out + margin <= y <= h - 1 - r_out - margin)
    if mirror:
        img = np.ascontiguousarray(img[:, ::-1])
    return img, truth
