"""Sub-pixel centres of round marks, holes and spheres.

Two refinements of a threshold blob are provided:

* ``method="fit"`` (default): least-squares fit of a blurred elliptical disk
  (:func:`~kinid.vision.disk_fit.fit_disk_model`),
  ``I = (bg + amp * erfc(R0 (rho - 1) / (s sqrt 2)) / 2) * (1 + gx x' + gy y')``
  with ``rho = sqrt(q^T M q)``, ``q = (x - cx, y - cy)`` and a linear
  illumination gradient (marks of radius >= 8 px), over an edge band.
  Centrally symmetric, so it returns the centre of the imaged ellipse.
* ``method="centroid"``: background-subtracted intensity-weighted centroid on an
  elliptical window, iterated so the window is centred (:func:`~kinid.vision.disk_fit.weighted_centroid`).

Both reach a few thousandths of a pixel at sigma = 2 grey levels (see
``benchmarks/bench_markers.py``), against about 0.05 px for a binary centroid
or an ellipse fitted to a threshold contour.

Pixel convention: x right, y down, centre of the top-left pixel at (0, 0).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinid.errors import ImageError

from .disk_fit import fit_disk_model, weighted_centroid

__all__ = ["CircleResult", "locate_disk", "locate_hole", "locate_sphere", "offset_from_image_centre",
           "fit_disk_model", "weighted_centroid", "as_gray", "noise_sigma"]


@dataclass(frozen=True)
class CircleResult:
    """Result of a round-feature locator.

    Attributes
    ----------
    found : bool
        Whether a feature was located.
    x_px, y_px : float
        Centre, pixels (NaN when not found).
    radius_px : float
        Radius (geometric mean of the ellipse's semi-axes), pixels.
    sigma_px : float
        Standard deviation of each centre coordinate estimated from the fit
        residuals, pixels.
    reason : str
        Empty when found, else why not.
    """

    found: bool
    x_px: float
    y_px: float
    radius_px: float
    sigma_px: float
    reason: str = ""


def _not_found(reason):
    return CircleResult(False, float("nan"), float("nan"), float("nan"), float("nan"), reason)


def as_gray(image) -> np.ndarray:
    """A float32 2-D grey image in grey levels 0..255; ImageError for anything else.

    Accepts a 2-D array or a 3/4-channel (BGR/BGRA) array. 8-bit images keep
    their levels; other types (uint16, float in [0, 1], ...) are stretched
    linearly from their minimum to their maximum onto 0..255, which changes no
    position.
    """
    arr = np.asarray(image)
    if not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)) \
            or np.issubdtype(arr.dtype, np.bool_):
        raise ImageError(f"expected a numeric image, got dtype {arr.dtype}")
    was_u8 = arr.dtype == np.uint8
    if arr.ndim == 3 and arr.shape[2] in (3, 4):
        arr = arr[..., :3].astype(np.float32) @ np.array([0.114, 0.587, 0.299], np.float32)
    if arr.ndim != 2 or arr.size == 0:
        raise ImageError(f"expected a 2-D grey image (or H x W x 3), got an array of shape {arr.shape}")
    out = arr.astype(np.float32)
    if not was_u8:
        finite = np.isfinite(out)
        if not finite.all():
            raise ImageError("image holds NaN or infinite values")
        mn, mx = float(out.min()), float(out.max())
        if mx > mn:
            out = (out - mn) * np.float32(255.0 / (mx - mn))
    return out


def noise_sigma(img) -> float:
    """Robust estimate of the additive noise standard deviation of an image, grey levels."""
    d = np.diff(img[:: max(1, img.shape[0] // 256)], axis=1).ravel()
    if d.size == 0:
        return 0.0
    return float(np.median(np.abs(d - np.median(d))) / 0.6745 / np.sqrt(2.0))


def _extremes(img):
    """Robust darkest and lightest levels: the k-th extreme values with k = max(12, 2e-5 N).

    A small feature (a few dozen pixels in a large image) still sets the level; single
    noisy pixels do not. Large images are 2 x 2 box-averaged first (faster, less noise).
    """
    if img.size > 1_000_000:
        h, w = img.shape
        img = img[: h // 2 * 2, : w // 2 * 2].reshape(h // 2, 2, w // 2, 2).mean(axis=(1, 3))
    flat = img.ravel()
    k = int(min(flat.size - 1, max(12, 2e-5 * flat.size)))
    lo = float(np.partition(flat, k)[k])
    hi = float(np.partition(flat, flat.size - 1 - k)[flat.size - 1 - k])
    return lo, hi


def _levels(img, polarity):
    """(sign, bg, ink, threshold): sign=+1 for light marks on dark, -1 for dark marks on light."""
    lo, hi = _extremes(img)
    border = np.concatenate([img[0], img[-1], img[:, 0], img[:, -1]])
    bg = float(np.median(border))
    if polarity == "auto":
        sign = -1 if (bg - lo) >= (hi - bg) else 1
    elif polarity == "dark":
        sign = -1
    elif polarity == "light":
        sign = 1
    else:
        raise ValueError(f"polarity must be 'auto', 'dark' or 'light', got {polarity!r}")
    ink = float(lo if sign < 0 else hi)
    return sign, bg, ink, 0.5 * (bg + ink)


def _blobs(img, sign, thr, min_area=12):
    """Connected components of the mark class: list of dicts with area, bbox, moments, circularity."""
    import cv2

    mask = ((img < thr) if sign < 0 else (img > thr)).astype(np.uint8)
    n, labels, stats, cents = cv2.connectedComponentsWithStats(mask, connectivity=8)
    h, w = img.shape
    out = []
    for k in range(1, n):
        x, y, bw, bh, area = (int(v) for v in stats[k])
        if area < min_area:
            continue
        touches = x == 0 or y == 0 or x + bw == w or y + bh == h
        out.append({"label": k, "area": area, "bbox": (x, y, bw, bh), "touches": touches,
                    "centroid": (float(cents[k][0]), float(cents[k][1]))})
    return out, labels


def _blob_shape(labels, blob):
    """Second moments of a blob: (cx, cy, cov 2x2, fill) where fill = area / (pi sqrt(det(4 cov)))."""
    x, y, bw, bh = blob["bbox"]
    sub = labels[y:y + bh, x:x + bw] == blob["label"]
    ys, xs = np.nonzero(sub)
    xs = xs + x
    ys = ys + y
    cx, cy = xs.mean(), ys.mean()
    cov = np.cov(np.vstack([xs - cx, ys - cy]), bias=True) + np.eye(2) / 12.0
    det = np.linalg.det(4 * cov)
    fill = blob["area"] / (np.pi * np.sqrt(det)) if det > 0 else 0.0
    ev = np.linalg.eigvalsh(cov)
    ratio = float(np.sqrt(ev[0] / ev[1])) if ev[1] > 0 else 0.0
    return float(cx), float(cy), cov, float(fill), ratio


def _crop(img, roi):
    if roi is None:
        return img, 0, 0
    try:
        x, y, w, h = (int(v) for v in roi)
    except (TypeError, ValueError):
        raise ValueError(f"roi must be (x, y, width, height) in pixels, got {roi!r}") from None
    H, W = img.shape
    x0, y0, x1, y1 = max(x, 0), max(y, 0), min(x + w, W), min(y + h, H)
    if x1 - x0 < 3 or y1 - y0 < 3:
        raise ValueError(f"roi {roi!r} does not overlap the {W}x{H} image")
    return img[y0:y1, x0:x1], x0, y0


def _locate_round(image, polarity, roi, method, prefer):
    img, ox, oy = _crop(as_gray(image), roi)
    sign, bg, ink, thr = _levels(img, polarity)
    nsig = noise_sigma(img)
    contrast = abs(ink - bg)
    if contrast < max(10.0, 8.0 * nsig):
        return _not_found(f"no contrast: mark-to-background difference {contrast:.1f} grey levels "
                          f"at noise {nsig:.1f}")
    blobs, labels = _blobs(img, sign, thr)
    cands = []
    for b in blobs:
        if b["touches"]:
            continue
        cx, cy, cov, fill, ratio = _blob_shape(labels, b)
        if 0.8 < fill < 1.2 and ratio > 0.5:
            cands.append((b, cx, cy, cov))
    if not cands:
        what = "dark" if sign < 0 else "light"
        return _not_found(f"no round {what} blob fully inside the image (threshold {thr:.0f})")
    if prefer == "centre":
        h, w = img.shape
        cands.sort(key=lambda c: (c[1] - (w - 1) / 2) ** 2 + (c[2] - (h - 1) / 2) ** 2)
    else:
        cands.sort(key=lambda c: -c[0]["area"])
    b, cx, cy, cov = cands[0]
    M0 = np.linalg.inv(4 * cov)
    # keep the window off other blobs: distance to the nearest other blob centroid
    R0 = np.linalg.det(M0) ** -0.25
    win = max(4.0, min(0.6 * R0, 12.0))
    for other, ocx, ocy, _ in cands[1:]:
        gap = np.hypot(ocx - cx, ocy - cy) - R0 - np.sqrt(other["area"] / np.pi)
        win = max(2.0, min(win, 0.5 * gap))
    if method == "fit":
        r = fit_disk_model(img, cx, cy, M0, window_px=win)
        if not r["ok"]:
            return _not_found(r["message"])
        return CircleResult(True, r["x"] + ox, r["y"] + oy, r["radius"], r["sigma"], "")
    if method == "centroid":
        xy = weighted_centroid(img, cx, cy, M0, bg, ink, window_px=win)
        if xy is None:
            return _not_found("mark too close to the image border")
        return CircleResult(True, xy[0] + ox, xy[1] + oy, float(R0), float("nan"), "")
    raise ValueError(f"method must be 'fit' or 'centroid', got {method!r}")


def locate_disk(image, *, polarity="auto", roi=None, method="fit") -> CircleResult:
    """Sub-pixel centre of a filled round mark (dark on light or light on dark).

    Parameters
    ----------
    image : array_like
        Grey image (H, W) or BGR (H, W, 3).
    polarity : {"auto", "dark", "light"}
        Mark darker or lighter than the background; ``auto`` decides from the
        border median against the extreme grey levels.
    roi : tuple of int or None
        (x, y, width, height) region to search, pixels; results are in full-image pixels.
    method : {"fit", "centroid"}
        Blurred-disk model fit or background-subtracted weighted centroid.

    Returns
    -------
    CircleResult
        The largest round blob fully inside the image/roi; ``found=False`` with
        a reason if none.
    """
    return _locate_round(image, polarity, roi, method, "largest")


def locate_hole(image, *, polarity="auto", roi=None, method="fit") -> CircleResult:
    """Sub-pixel centre of a hole (dark, or bright when back-lit); the round blob nearest the image centre.

    Parameters are those of :func:`locate_disk`.
    """
    return _locate_round(image, polarity, roi, method, "centre")


def locate_sphere(image, *, polarity="auto", roi=None, n_rays=180) -> CircleResult:
    """Centre of a sphere's image from its outline: sub-pixel edge points on rays, least-squares circle.

    The sphere's interior may be shaded (highlights, gradients), so only the
    outline is used: the blob nearest the image centre gives a start circle;
    along ``n_rays`` rays from its centre the strongest gradient of the
    correct sign near the start radius is located with a parabolic peak fit;
    a circle is fitted (algebraic, then geometric) with one round of outlier
    rejection.

    Parameters
    ----------
    image : array_like
        Grey image (H, W) or BGR (H, W, 3).
    polarity : {"auto", "dark", "light"}
        Sphere darker or lighter than the background.
    roi : tuple of int or None
        (x, y, width, height) region to search, pixels.
    n_rays : int
        Number of rays.
    """
    import cv2
    from scipy.optimize import least_squares

    img, ox, oy = _crop(as_gray(image), roi)
    sign, bg, ink, _ = _levels(img, polarity)
    nsig = noise_sigma(img)
    if abs(ink - bg) < max(10.0, 8.0 * nsig):
        return _not_found("no contrast between sphere and background")
    # a threshold near the background keeps the whole (shaded) sphere in one blob
    thr = bg + sign * max(8.0 * nsig, 0.2 * abs(ink - bg))
    blobs, labels = _blobs(cv2.GaussianBlur(img, (5, 5), 1.0), sign, thr)
    h, w = img.shape
    cands = []
    for b in blobs:
        if b["touches"]:
            continue
        cx, cy, cov, fill, ratio = _blob_shape(labels, b)
        if 0.7 < fill < 1.3 and ratio > 0.5:
            cands.append((b, cx, cy, cov))
    if not cands:
        return _not_found("no round blob fully inside the image")
    cands.sort(key=lambda c: (c[1] - (w - 1) / 2) ** 2 + (c[2] - (h - 1) / 2) ** 2)
    b, cx, cy, cov = cands[0]
    r0 = float(2.0 * np.linalg.det(cov) ** 0.25)  # a uniform disk has cov = r^2/4 I
    sm = cv2.GaussianBlur(img, (0, 0), 1.0)
    ang = np.linspace(0, 2 * np.pi, int(n_rays), endpoint=False)
    t = np.arange(-0.15 * r0 - 3.0, 0.15 * r0 + 3.5, 0.5)
    rr = r0 + t
    px = cx + np.cos(ang)[:, None] * rr[None, :]
    py = cy + np.sin(ang)[:, None] * rr[None, :]
    if px.min() < 1 or py.min() < 1 or px.max() > w - 2 or py.max() > h - 2:
        return _not_found("sphere outline too close to the image border")
    prof = cv2.remap(sm, px.astype(np.float32), py.astype(np.float32), cv2.INTER_LINEAR)
    grad = np.gradient(prof, axis=1) * (-1.0 if sign > 0 else 1.0)  # positive across the outline going out
    k = np.argmax(grad, axis=1)
    ok = (k > 0) & (k < len(t) - 1)
    i = np.arange(len(ang))[ok]
    kk = k[ok]
    g0, g1, g2 = grad[i, kk - 1], grad[i, kk], grad[i, kk + 1]
    den = g0 - 2 * g1 + g2
    off = np.where(den < 0, 0.5 * (g0 - g2) / np.where(den < 0, den, -1), 0.0)
    rad = rr[kk] + off * 0.5
    ex = cx + np.cos(ang[i]) * rad
    ey = cy + np.sin(ang[i]) * rad
    strong = g1 > 0.25 * np.median(g1)
    ex, ey = ex[strong], ey[strong]
    if ex.size < 12:
        return _not_found("too few outline points")

    def resid(p):
        return np.hypot(ex - p[0], ey - p[1]) - p[2]

    p = least_squares(resid, [cx, cy, r0]).x
    d = resid(p)
    keep = np.abs(d) < max(3 * 1.4826 * np.median(np.abs(d)), 0.1)
    ex, ey = ex[keep], ey[keep]
    res = least_squares(resid, p)
    p = res.x
    sd = float(np.sqrt(res.fun @ res.fun / max(ex.size - 3, 1)))
    sigma = sd * np.sqrt(2.0 / ex.size)
    return CircleResult(True, float(p[0]) + ox, float(p[1]) + oy, float(p[2]), float(sigma), "")


def offset_from_image_centre(result, image_shape):
    """(dx_px, dy_px) of a located centre from the image centre ((W-1)/2, (H-1)/2).

    Raises
    ------
    ImageError
        If ``result.found`` is False (with its reason).
    """
    if not result.found:
        raise ImageError(f"no feature located: {result.reason}")
    h, w = int(image_shape[0]), int(image_shape[1])
    return (float(result.x_px) - (w - 1) / 2.0, float(result.y_px) - (h - 1) / 2.0)
