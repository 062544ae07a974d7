"""Sub-pixel location of the one round fiducial in a stage image.

Uses :func:`vision.circles.locate_disk` (blurred-disk model fit) when that
module is available and finds the disk, otherwise a background-subtracted
intensity-weighted centroid (both polarities). An image
that does not show one complete fiducial raises :class:`ImageError`.
"""
from __future__ import annotations

import numpy as np

from kinid.errors import ImageError

__all__ = ["locate_fiducial", "centroid_locate"]

#: Minimum fiducial/background contrast, grey levels, and in multiples of the image noise.
MIN_CONTRAST = 20.0
MIN_CONTRAST_SIGMAS = 8.0


def _check_image(image, what):
    img = np.asarray(image)
    if img.ndim != 2 or img.size == 0:
        raise ImageError(f"{what}: expected a 2-D grey image, got an array of shape {img.shape}")
    return img.astype(np.float64)


def centroid_locate(image, *, what="image"):
    """Fiducial centre by a background-subtracted intensity-weighted centroid.

    Parameters
    ----------
    image : array_like, shape (H, W)
        Grey image with one round fiducial, dark on light or light on dark.
    what : str
        Name of the image in error messages.

    Returns
    -------
    tuple of float
        (x_px, y_px, radius_px).

    Raises
    ------
    ImageError
        When no fiducial stands out of the background, or it touches the border.
    """
    import cv2

    img = _check_image(image, what)
    h, w = img.shape
    bg = float(np.median(img))
    lo, hi = np.percentile(img, [0.05, 99.95])
    sign = 1.0 if (hi - bg) >= (bg - lo) else -1.0
    contrast = max(hi - bg, bg - lo)
    # Noise from horizontal neighbour differences (robust: MAD).
    d = np.diff(img, axis=1).ravel()
    noise = 1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(2.0)
    if contrast < max(MIN_CONTRAST, MIN_CONTRAST_SIGMAS * noise):
        raise ImageError(f"{what}: no fiducial found (contrast {contrast:.1f} grey levels against a "
                         f"background of {bg:.0f}, noise {noise:.1f}); is the fiducial in the field of view?")
    s = sign * (img - bg)
    mask = (s > 0.5 * contrast).astype(np.uint8)
    n, labels, stats, cents = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n < 2:
        raise ImageError(f"{what}: no fiducial found")
    k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    x0, y0, bw, bh, area = (int(v) for v in stats[k, :5])
    if x0 == 0 or y0 == 0 or x0 + bw >= w or y0 + bh >= h:
        raise ImageError(f"{what}: the fiducial touches the image border (bounding box x {x0}..{x0 + bw - 1}, "
                         f"y {y0}..{y0 + bh - 1} px in a {w} x {h} image); move it into the field of view")
    r = float(np.sqrt(area / np.pi))
    cx, cy = (float(v) for v in cents[k])
    margin = 6.0
    for _ in range(3):
        r_roi = r + margin
        xa, xb = int(np.floor(cx - r_roi - margin)), int(np.ceil(cx + r_roi + margin)) + 1
        ya, yb = int(np.floor(cy - r_roi - margin)), int(np.ceil(cy + r_roi + margin)) + 1
        if xa < 0 or ya < 0 or xb > w or yb > h:
            raise ImageError(f"{what}: the fiducial is too close to the image border to be located "
                             f"(centre near ({cx:.0f}, {cy:.0f}) px, radius {r:.0f} px)")
        sub = img[ya:yb, xa:xb]
        yy, xx = np.mgrid[ya:yb, xa:xb]
        rr = np.hypot(xx - cx, yy - cy)
        ring = (rr > r_roi) & (rr <= r_roi + margin)
        local_bg = float(np.median(sub[ring]))
        inside = rr <= r_roi
        wgt = sign * (sub[inside] - local_bg)
        total = wgt.sum()
        if not total > 0:
            raise ImageError(f"{what}: no fiducial found (no signal above the local background)")
        cx = float((wgt * xx[inside]).sum() / total)
        cy = float((wgt * yy[inside]).sum() / total)
    return cx, cy, r


def locate_fiducial(image, *, what="image"):
    """Centre (x_px, y_px) of the single round fiducial in ``image``.

    Parameters
    ----------
    image : array_like, shape (H, W)
        Grey image (uint8 or float).
    what : str
        Name of the image in error messages (e.g. "image after move 7").

    Returns
    -------
    tuple of float
        (x_px, y_px) in OpenCV pixel convention.

    Raises
    ------
    ImageError
        When no fiducial is found.
    """
    _check_image(image, what)
    try:
        from kinid.vision import locate_disk
    except ImportError:
        locate_disk = None
    reason = None
    if locate_disk is not None:
        res = locate_disk(np.asarray(image))
        if res.found:
            return float(res.x_px), float(res.y_px)
        reason = res.reason
    try:
        x, y, _ = centroid_locate(image, what=what)
    except ImageError as exc:
        if reason is None:
            raise
        raise ImageError(f"{what}: no fiducial found ({reason}; centroid: "
                         f"{exc.message.removeprefix(what + ': ')})") from None
    return x, y
