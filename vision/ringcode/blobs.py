"""Candidate centre circles of ring-coded marks: round blobs of a thresholded image (8-connected
components whose shape matches their moment ellipse) and the global thresholds that separate ink from
background. :mod:`kinid.vision.ringcode` searches them level by level on a scale pyramid.
"""
from __future__ import annotations

import numpy as np

from ..circles import noise_sigma
from ..disk_fit import _det2
from .read import _RHO_MAX

__all__: list = []


def _components(mask, min_area, d_range, inside=None):
    """The 8-connected components of ``mask`` whose bounding box allows a round blob of ``d_range``.

    Returns ``[(labels, stats, k, (x0, y0), holed)]`` in raster order of the components' first pixels:
    component ``k`` of ``connectedComponentsWithStats`` run on the box ``labels`` covers (from
    (x0, y0) in ``mask``). The outlines (``findContours``, far cheaper than labelling the whole
    mask) give every component's box; only the boxes that can hold a blob passing the tests of
    :func:`_blobs` (area at least ``min_area`` and the equivalent diameter in ``d_range``, filling
    50-95 % of the box, the box inside the mask and at most 3 times longer than wide) are labelled.

    ``inside``: ``(scale, (x0, y0), marks)`` with ``marks`` (k, 3) the decoded marks (x, y, radius;
    full-resolution pixels) and the mask's scale and offset in the level: a component whose box lies
    so deep inside the ring of a mark that its centre and any blob near it (as :func:`_detect_pyramid`
    compares candidates) are inside the ring too is left out (the search would skip it anyway).
    """
    import cv2

    contours, hier = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        return []
    outer = np.flatnonzero(hier[0][:, 3] < 0)  # outer outlines: one per component
    lens = np.fromiter((len(contours[i]) for i in outer), np.int64, outer.size)
    pts = np.concatenate([contours[i] for i in outer]).reshape(-1, 2)
    starts = np.concatenate([[0], np.cumsum(lens)[:-1]])
    xa, xb = np.minimum.reduceat(pts[:, 0], starts), np.maximum.reduceat(pts[:, 0], starts)
    ya, yb = np.minimum.reduceat(pts[:, 1], starts), np.maximum.reduceat(pts[:, 1], starts)
    bw, bh = xb - xa + 1, yb - ya + 1
    h, w = mask.shape
    box = (bw * bh).astype(float)
    a_min = max(float(min_area), 0.25 * np.pi * d_range[0] ** 2)
    a_max = 0.25 * np.pi * d_range[1] ** 2
    ok = ((xa > 0) & (ya > 0) & (xb < w - 1) & (yb < h - 1)
          & (np.maximum(bw, bh) <= 3 * np.minimum(bw, bh))
          & (0.95 * box >= a_min * (1 - 1e-9)) & (0.5 * box <= a_max * (1 + 1e-9)))
    if inside is not None and len(inside[2]) and ok.any():
        s, (ox, oy), marks = inside
        # the blob's centre lies in the box of its pixel centres, its radius is at most
        # s sqrt(bw bh) (moment ellipse of pixels spread over the box)
        x_lo, x_hi = (xa + ox + 0.5) * s - 0.5, (xb + ox + 0.5) * s - 0.5
        y_lo, y_hi = (ya + oy + 0.5) * s - 0.5, (yb + oy + 0.5) * s - 0.5
        r_bound = s * np.sqrt(box)
        mx, my, mr = (marks[:, c][None, :] for c in range(3))
        far = np.hypot(np.maximum(np.abs(x_lo[:, None] - mx), np.abs(x_hi[:, None] - mx)),
                       np.maximum(np.abs(y_lo[:, None] - my), np.abs(y_hi[:, None] - my)))
        ok &= ~np.any(far <= _RHO_MAX * mr - 0.5 * r_bound[:, None] - 1e-6, axis=1)
    found = []
    for j in np.flatnonzero(ok):
        c = contours[outer[j]]
        # at most area + perimeter / 2 + 1 pixels lie inside or on the outline (Pick's theorem; a
        # part traced twice counts twice in the perimeter): too few for a blob, no labelling
        if cv2.contourArea(c) + 0.5 * cv2.arcLength(c, True) + 1.0 < a_min * (1 - 1e-9):
            continue
        c = c.reshape(-1, 2)
        top = c[c[:, 1] == ya[j]]
        found.append((int(ya[j]), int(top[:, 0].min()), j))
    out = []
    for y_first, x_first, j in sorted(found):
        x0, y0 = int(xa[j]), int(ya[j])
        _, labels, stats, _ = cv2.connectedComponentsWithStats(
            mask[y0:y0 + int(bh[j]), x0:x0 + int(bw[j])], connectivity=8)
        holed = hier[0][outer[j], 2] >= 0  # an outer outline's children are the component's holes
        out.append((labels, stats, int(labels[y_first - y0, x_first - x0]), (x0, y0), bool(holed)))
    return out


def _blobs(mask, scale, min_area, d_range=(0.0, np.inf), fill_holes=True, offset=(0, 0), marks=None):
    """Round blobs of a binary mask: list of (x, y, M, area) in full-resolution pixels.

    ``mask`` is an image ``scale`` times smaller than the full-resolution one. A blob is kept when
    its equivalent diameter (mask pixels) lies in ``d_range``, it does not touch the border, and
    its shape matches its own moment ellipse (holes in it filled first with ``fill_holes``). ``offset``:
    the position of the mask's top-left pixel in the level. ``marks``: decoded marks (x, y, radius) whose
    ring interior need not be searched (:func:`_components`).
    """
    import cv2

    comps = _components(mask, min_area, d_range, None if marks is None else (scale, offset, marks))
    h, w = mask.shape
    out = []
    for labels, stats, k, (ox, oy), holed in comps:
        x, y, bw, bh, area = (int(v) for v in stats[k])
        # the cheap tests, exact on the component (noise and texture of a photo give many)
        d = np.sqrt(4.0 * area / np.pi)
        x, y = x + ox, y + oy
        if not ((area >= min_area) and (d_range[0] <= d < d_range[1])
                and x > 0 and y > 0 and x + bw < w and y + bh < h
                and max(bw, bh) <= 3 * min(bw, bh) and area >= 0.5 * bw * bh
                and area <= 0.95 * bw * bh):  # a filled rectangle (e.g. a cut-off corner of something): not a circle
            continue
        sub = (labels[y - oy:y - oy + bh, x - ox:x - ox + bw] == k).astype(np.uint8)
        if fill_holes and holed:
            # a hole (a dot printed in the centre circle, a reflection) does not make it less round
            outside = cv2.copyMakeBorder(1 - sub, 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=1)
            cv2.floodFill(outside, None, (0, 0), 2)
            sub = (outside[1:-1, 1:-1] != 2).astype(np.uint8)
            area = int(np.count_nonzero(sub))
        mo = cv2.moments(sub, binaryImage=True)
        cx, cy = mo["m10"] / mo["m00"], mo["m01"] / mo["m00"]  # relative to the bbox corner
        # moment covariance (+ 1/12: the pixel's own extent) and the ellipse q^T M q <= 1 of equal moments
        c00 = mo["mu20"] / mo["m00"] + 1.0 / 12.0
        c01 = mo["mu11"] / mo["m00"]
        c11 = mo["mu02"] / mo["m00"] + 1.0 / 12.0
        det = c00 * c11 - c01 * c01
        if not det > 0:
            continue
        M = np.array([[c11, -c01], [-c01, c00]]) / (4.0 * det)
        # overlap of the blob with its moment ellipse (a disk: ~1; a bar or an arc: clearly less),
        # on a grid of at most ~48 x 48 points
        stp = max(1, max(bw, bh) // 48)
        qx = np.arange(0, bw, stp) - cx  # a row and a column, broadcast over the grid
        qy = (np.arange(0, bh, stp) - cy)[:, None]
        ell = ((M[0, 0] * qx * qx) + (2 * M[0, 1] * qx) * qy + (M[1, 1] * qy * qy)) <= 1.0
        inb = sub[::stp, ::stp].astype(bool)
        inter = np.count_nonzero(ell & inb) * stp * stp
        ell_area = np.pi / np.sqrt(_det2(M))  # the ellipse may extend past the bbox
        union = area + ell_area - inter
        if inter / union < 0.85:
            continue
        X = (cx + x + offset[0] + 0.5) * scale - 0.5
        Y = (cy + y + offset[1] + 0.5) * scale - 0.5
        out.append((X, Y, M / (scale * scale), area * scale * scale))
    return out


def _candidates(small, sign, thr, scale, min_area):
    """Round blobs of ``small`` beyond the global threshold ``thr``: list of (x, y, M, area), full-resolution pixels."""
    mask = ((small < thr) if sign < 0 else (small > thr)).astype(np.uint8)
    return _blobs(mask, scale, min_area, fill_holes=False)


def _global_options(small, polarity):
    """Global thresholds ``[(sign, threshold), ...]``, the polarity of stronger contrast first.

    Background = the histogram's median (marks cover well under half of any view), ink = the extreme
    reached by at least k pixels (a single small mark in a large image still counts); a polarity whose
    contrast is under ``max(10, 6 noise)`` is left out.
    """
    import cv2

    hist = cv2.calcHist([small], [0], None, [256], [0, 256]).ravel()
    cum = np.cumsum(hist)
    total = cum[-1]
    k_min = max(12.0, 2e-5 * total)
    bg = int(np.searchsorted(cum, total / 2))
    lo = int(np.searchsorted(cum, k_min))
    hi = int(np.searchsorted(cum, total - k_min))
    need = max(10.0, 6.0 * noise_sigma(small.astype(np.float32)))
    options = []
    if bg - lo >= need:
        options.append((bg - lo, -1, 0.5 * (bg + lo)))
    if hi - bg >= need:
        options.append((hi - bg, 1, 0.5 * (bg + hi)))
    options.sort(reverse=True)  # the stronger contrast first
    wanted = {"dark": -1, "light": 1}.get(polarity)
    return [(sg, t) for _, sg, t in options if wanted is None or sg == wanted]


def _as_u8(img):
    """``img`` (grey levels 0..255) as a contiguous uint8 array."""
    if img.dtype != np.uint8:
        img = np.clip(np.rint(img), 0, 255).astype(np.uint8)  # as_gray put it on 0..255
    return np.ascontiguousarray(img)
