"""Detection and decoding of ring-coded marks (after the ring-coded target of CN "monocular measurement of planar contour error").

A mark is a centre circle (not coded) surrounded by a ring of ``n`` equal
angular elements, each printed (1) or not (0). The code is the smallest value
over all cyclic rotations of the ``n`` bits read clockwise as seen in the image
(x right, y down), first bit most significant (``clockwise=False`` reads them
the other way round, as some other systems do).

Detection (:func:`detect_markers`):

1. on a scale pyramid (2 x 2 box averages), search each level for the centre
   circles it resolves (6.5-14 level pixels across; the finest level also
   smaller, the coarsest also larger ones): threshold it midway between the
   local background (tile median) and the local ink level, and keep blobs whose
   shape matches their moment ellipse (candidate centre circles);
2. affine-normalise each candidate with its ellipse and sample the full-
   resolution image on a polar grid (so perspective and anisotropic scale are
   undone): locate the ring band radially, read the angular profile (per
   angle the most inked radius of the band);
3. find the element phase from the profile's edges, read each element's mean
   ink; an element that is not clearly printed or clearly blank, a ring band
   that is not where a ring belongs, or ink in the gap between circle and ring
   rejects the mark (a dropped mark is better than a wrong code);
4. refine the centre circle's centre by a blurred-ellipse fit
   (:func:`vision.circles.fit_disk_model`).

:func:`decode_from_segments` is the patent's arithmetic on segment element
counts and the angles between segment centroids.
"""
from __future__ import annotations

import numpy as np

from ..circles import as_gray
from ..disk_fit import _det2
from .blobs import _as_u8, _blobs, _candidates, _global_options
from .read import Marker, _RHO_MAX, _decode_one, canonical_code, decode_from_segments, read_ring  # noqa: F401 (re-exported)

__all__ = ["Marker", "canonical_code", "decode_from_segments", "detect_markers", "read_ring"]


# -- the candidate search on a scale pyramid ---------------------------------------------------

#: Level k of the pyramid is the image box-averaged by ``2**k`` times the finest factor. Every level
#: but the finest and the coarsest searches centre circles of equivalent diameter in this range
#: (level pixels): large enough to be separated from the ring by the threshold, small enough that
#: the next level resolves the larger ones (the ranges of two levels overlap a little).
_LEVEL_D = (6.5, 14.0)

#: The finest level, when it is the image itself (under 2048 px), also takes centre circles down to
#: this equivalent diameter (pixels).
_FINEST_D = 3.5

#: Side of the tiles of the local levels (level pixels); a mark of the level's range spans at most
#: 3.2 * 14 = 45 of them.
_TILE_PX = 64

#: The pyramid stops before a level's shorter side would fall under this (pixels).
_MIN_LEVEL_PX = 64


def _halve(a):
    """2 x 2 box average of ``a`` (an odd last row or column dropped), uint8."""
    import cv2

    h, w = a.shape
    return cv2.resize(a[: h // 2 * 2, : w // 2 * 2], (w // 2, h // 2), interpolation=cv2.INTER_AREA)


def _pyramid(img8):
    """``[(factor, level image)]`` from fine to coarse: factor 1 for images under 2048 px, else 2
    (a centre circle of 13 px diameter is then 6.5 level pixels), then doubling."""
    h, w = img8.shape
    s = 1 if max(h, w) < 2048 else 2
    cur = img8 if s == 1 else _halve(img8)
    levels = [(s, cur)]
    while min(cur.shape) // 2 >= _MIN_LEVEL_PX:
        cur = _halve(cur)
        s *= 2
        levels.append((s, cur))
    return levels


def _noise_sigma_u8(img):
    """:func:`vision.circles.noise_sigma` of a uint8 image, the same value from histograms (integer differences)."""
    d = np.diff(img[:: max(1, img.shape[0] // 256)].astype(np.int16), axis=1).ravel()
    if d.size == 0:
        return 0.0
    lo, hi = (d.size - 1) // 2, d.size // 2  # the two middle ranks (equal for an odd count)

    def middle_sum(values, offset):  # the sum of the values of ranks lo and hi
        cum = np.cumsum(np.bincount(values + offset))
        return int(np.searchsorted(cum, lo + 1)) + int(np.searchsorted(cum, hi + 1)) - 2 * offset

    med2 = middle_sum(d, 255)  # twice the median
    mad = np.float32(middle_sum(np.abs(2 * d.astype(np.int32) - med2), 0) / 4.0)
    return float(mad / 0.6745 / np.sqrt(2.0))


def _nearest_spans(n_dst, n_src):
    """Start of each source cell's footprint in a nearest-neighbour upscale of ``n_src`` cells to ``n_dst``
    pixels (as ``cv2.resize`` with ``INTER_NEAREST`` maps pixel x to cell ``floor(x n_src / n_dst)``), and
    ``n_dst`` at the end: cell j covers pixels ``[spans[j], spans[j + 1])``."""
    src = np.minimum(np.floor(np.arange(n_dst) * (1.0 / (n_dst / n_src))).astype(np.int64), n_src - 1)
    return np.searchsorted(src, np.arange(n_src + 1))


_TILE_BINS = {}


def _tile_bins(ny, nx, t):
    """(ny t, nx t) int64: 256 times the index of each pixel's tile (of t x t pixels), cached."""
    key = (ny, nx, t)
    bins = _TILE_BINS.get(key)
    if bins is None:
        if len(_TILE_BINS) >= 8:
            _TILE_BINS.clear()
        bins = ((np.arange(ny * t, dtype=np.int64) // t * (nx * 256))[:, None]
                + (np.arange(nx * t, dtype=np.int64) // t * 256)[None, :])
        bins.flags.writeable = False
        _TILE_BINS[key] = bins
    return bins


def _local_masks(level, coarse, polarity):
    """Binary masks ``[(sign, mask, (x0, y0))]`` of ``level`` thresholded midway between the local background and
    ink; each mask covers the box of the level from (x0, y0) that holds tiles with contrast.

    The levels are those of :func:`_global_options`, but per tile of ``_TILE_PX`` level pixels (taken
    from ``coarse``, the next level, 2 x 2 box-averaged: less noise, a quarter of the work):
    background = the median of the tile or of one of its 8 neighbours (the one farthest from ink), ink =
    the 0.5 % extreme over the tile and its neighbours (a mark across a tile border counts in both).
    Thresholds are interpolated between tile centres; a tile whose contrast is under
    ``max(10, 6 noise)`` gives no candidates. This follows lighting that changes across the image
    and marks printed on patches of another grey.
    """
    import cv2

    h, w = level.shape
    t = _TILE_PX // 2
    ch, cw = coarse.shape
    ny, nx = -(-ch // t), -(-cw // t)
    pad = cv2.copyMakeBorder(coarse, 0, ny * t - ch, 0, nx * t - cw, cv2.BORDER_REFLECT_101)
    n = t * t
    k = max(4, n // 200)
    # the k-th darkest, the median and the k-th lightest grey level of every tile, from the tiles'
    # histograms (one bincount; a partition of each tile's pixels takes several times longer)
    cum = np.cumsum(np.bincount((_tile_bins(ny, nx, t) + pad).ravel(), minlength=ny * nx * 256)
                    .reshape(ny, nx, 256), axis=2)
    lo_t, bg_t, hi_t = ((cum <= q).sum(axis=2).astype(np.uint8) for q in (k, n // 2, n - 1 - k))
    kernel = np.ones((3, 3), np.uint8)

    def spread(a, sign):  # the darkest (sign -1) or lightest (+1) over the tile and its neighbours
        op = cv2.erode if sign < 0 else cv2.dilate
        return op(a, kernel, borderType=cv2.BORDER_REPLICATE).astype(np.float32)

    need = max(10.0, 6.0 * _noise_sigma_u8(level[:: max(1, h // 64)]))  # from ~64 rows
    wanted = {"dark": (-1,), "light": (1,)}.get(polarity, (-1, 1))
    out = []
    for sign in wanted:
        # ink: the extreme near the tile; background: the neighbouring tile median farthest from ink
        # (a tile mostly covered by something dark, e.g. the frame of a screen, or by a large mark
        # does not pull the background of dark marks next to it down)
        ink = spread(lo_t if sign < 0 else hi_t, sign)
        bg = spread(bg_t, -sign)
        valid = np.abs(bg - ink) >= need
        if not valid.any():
            continue
        # uint8 maps (fast to resize and compare); a tile without contrast gets the threshold
        # nothing passes (0 for dark marks, 255 for light ones)
        thr = cv2.resize(np.clip(np.rint(0.5 * (bg + ink)), 1, 254).astype(np.uint8), (w, h),
                         interpolation=cv2.INTER_LINEAR)
        if valid.all():  # contrast everywhere: the threshold map alone
            mask = cv2.compare(level, thr, cv2.CMP_LT if sign < 0 else cv2.CMP_GT)
            out.append((sign, mask, (0, 0)))
            continue
        # only the box around the tiles with contrast is searched (with a blank border, so that a blob
        # cut by the box is one cut by the tiles without contrast, not by the image border)
        ty, tx = np.nonzero(valid)
        ya, yb = int(ty.min() * h // ny), int(min(h, -(-(ty.max() + 1) * h // ny)))
        xa, xb = int(tx.min() * w // nx), int(min(w, -(-(tx.max() + 1) * w // nx)))
        ya, xa = max(0, ya - 1), max(0, xa - 1)
        yb, xb = min(h, yb + 1), min(w, xb + 1)
        # the pixels of a tile without contrast (the tile's nearest-neighbour footprint) get the
        # threshold nothing passes
        rows, cols = _nearest_spans(h, ny), _nearest_spans(w, nx)
        never = 0 if sign < 0 else 255
        for i in range(ny):
            bad = np.flatnonzero(~valid[i])
            if bad.size == 0 or rows[i + 1] <= ya or rows[i] >= yb:
                continue
            # runs of consecutive tiles without contrast: one slice each
            cut = np.flatnonzero(np.diff(bad) > 1)
            for j0, j1 in zip(bad[np.r_[0, cut + 1]], bad[np.r_[cut, bad.size - 1]]):
                thr[rows[i]:rows[i + 1], cols[j0]:cols[j1 + 1]] = never
        sub = (slice(ya, yb), slice(xa, xb))
        mask = cv2.compare(level[sub], thr[sub], cv2.CMP_LT if sign < 0 else cv2.CMP_GT)
        out.append((sign, mask, (xa, ya)))
    return out


def _level_candidates(levels, i, polarity, marks=None):
    """Candidate centre circles of level ``i`` of ``levels``: ``[(x, y, M, sign)]``, full-resolution pixels.

    The level searches the sizes it resolves (``_LEVEL_D``; the finest also smaller, the coarsest all
    larger ones) with local thresholds (:func:`_local_masks`; the coarsest level, the whole image at
    once, with the global ones). ``marks``: the decoded marks (x, y, radius), whose ring interiors are
    not searched.
    """
    s, lv = levels[i]
    last = i == len(levels) - 1
    d_lo = _FINEST_D if (i == 0 and s == 1) else _LEVEL_D[0]
    d_hi = np.inf if last else _LEVEL_D[1]
    if last:
        masks = [(sign, ((lv < thr) if sign < 0 else (lv > thr)).astype(np.uint8), (0, 0))
                 for sign, thr in _global_options(lv, polarity)]
    else:
        masks = _local_masks(lv, levels[i + 1][1], polarity)
    out = []
    for sign, mask, off in masks:
        out.extend((X, Y, M, sign) for X, Y, M, _area in
                   _blobs(mask, s, min_area=12, d_range=(d_lo, d_hi), offset=off, marks=marks))
    return out


def _detect_pyramid(img, img8, n, polarity, refine, clockwise):
    """Search the levels from coarse to fine and read every candidate; returns the decoded Markers.

    A candidate inside the ring of a mark already read (a ring element of a large mark, found on a
    finer level) or at the place and size of one already tried on a coarser level is not read again:
    :func:`_keep_outermost` would drop the first, the second gives nothing new.
    """
    levels = _pyramid(img8)
    markers = []
    mk = np.empty((0, 3))  # decoded: x, y, radius
    tried = np.empty((0, 3))  # candidates of coarser levels: x, y, radius
    for i in range(len(levels) - 1, -1, -1):
        s = levels[i][0]
        cands = [(X, Y, M, sign, float(_det2(M) ** -0.25)) for X, Y, M, sign in
                 _level_candidates(levels, i, polarity, mk)]
        cands.sort(key=lambda c: -c[4])
        this = []
        for X, Y, M, sign, r in cands:
            this.append((X, Y, r))
            if len(mk) and np.any(np.hypot(mk[:, 0] - X, mk[:, 1] - Y) <= _RHO_MAX * mk[:, 2]):
                continue
            if len(tried):
                ratio = tried[:, 2] / r
                if np.any((np.hypot(tried[:, 0] - X, tried[:, 1] - Y) < 0.5 * np.minimum(tried[:, 2], r))
                          & (ratio > 0.67) & (ratio < 1.5)):
                    continue
            m = _decode_one(img, X, Y, M, sign, n, refine, s, clockwise=clockwise)
            if m is not None:
                markers.append(m)
                mk = np.vstack([mk, [m.x_px, m.y_px, m.radius_px]])
        if this:
            tried = np.vstack([tried, np.array(this)])
    return markers


def _keep_outermost(markers):
    """A ring element mistaken for a centre circle lies inside a real mark's ring: keep the larger mark."""
    markers = sorted(markers, key=lambda m: -m.radius_px)
    kx, ky, kr = [], [], []
    kept = []
    for m in markers:
        if kx:
            d = np.hypot(np.asarray(kx) - m.x_px, np.asarray(ky) - m.y_px)
            if np.any(d <= _RHO_MAX * np.asarray(kr)):
                continue
        kept.append(m)
        kx.append(m.x_px)
        ky.append(m.y_px)
        kr.append(m.radius_px)
    kept.sort(key=lambda m: (m.y_px, m.x_px))
    return kept


def _check_args(image, bits, polarity, refine, clockwise):
    from kinid.checks import check_choice, check_image, check_int

    n = check_int("bits", bits, minimum=3, maximum=30)
    check_image("image", image)
    check_choice("polarity", polarity, ("auto", "dark", "light"))
    check_choice("refine", refine, ("fit", "centroid"))
    if not isinstance(clockwise, (bool, np.bool_)):
        from kinid.errors import DataError

        raise DataError(f"must be True or False, got {clockwise!r}", parameter="clockwise")
    arr = np.asarray(image)
    img = arr if (arr.ndim == 2 and arr.dtype == np.uint8) else as_gray(arr)
    return n, img


def detect_markers(image, bits=12, *, polarity="auto", refine="fit", clockwise=True) -> list:
    """Detect and decode ring-coded marks.

    Parameters
    ----------
    image : array_like
        Grey image (H, W) or BGR (H, W, 3).
    bits : int
        Ring elements per mark.
    polarity : {"auto", "dark", "light"}
        Dark marks on a light background, light on dark, or ``auto`` (both; each part of the
        image is searched in the polarities its local contrast allows).
    refine : {"fit", "centroid"}
        Centre refinement: blurred-ellipse model fit (most accurate) or
        background-subtracted weighted centroid (faster).
    clockwise : bool
        Direction in which the ring's bits are read, as seen in the image (x right, y down):
        clockwise (default, this project's convention and its boards) or counter-clockwise (other
        systems' convention, e.g. CCTDecode). The two readings of one mark are each other's bit
        mirror image; a mirror-symmetric code reads the same both ways.

    Returns
    -------
    list of Marker
        Sorted by y then x. Marks whose ring leaves the image, or whose ring
        cannot be read with confidence, are left out.

    Notes
    -----
    Candidates come from a scale pyramid (factor 1, or 2 for images of 2048 px and more, then
    doubling): each level searches the centre-circle sizes it resolves (6.5-14 level pixels), with
    thresholds from the local background and ink levels; every candidate is then read at full
    resolution. Centre circles down to 7 px diameter (images under 2048 px) or 13 px (larger
    images) are searched.
    """
    n, img = _check_args(image, bits, polarity, refine, clockwise)
    markers = _detect_pyramid(img, _as_u8(img), n, polarity, refine, bool(clockwise))
    return _keep_outermost(markers)


def _detect_single_scale(image, bits=12, *, polarity="auto", refine="fit", clockwise=True) -> list:
    """The earlier candidate search: one global threshold on a copy shrunk to about 1024 px.

    Kept as the reference that ``benchmarks/bench_photo_markers.py`` runs on overlapping tiles
    (the peer of :func:`detect_markers`); the reading of each candidate is the same.
    """
    import cv2

    n, img = _check_args(image, bits, polarity, refine, clockwise)
    h, w = img.shape
    scale = max(1, int(max(h, w) // 1024))
    small = cv2.resize(img, (w // scale, h // scale), interpolation=cv2.INTER_AREA) if scale > 1 else img
    small = _as_u8(small)
    markers = []
    for sign, thr in _global_options(small, polarity):
        for X, Y, M, _area in _candidates(small, sign, thr, scale, min_area=12):
            m = _decode_one(img, X, Y, M, sign, n, refine, scale, clockwise=bool(clockwise))
            if m is not None:
                markers.append(m)
        if markers:
            break
    return _keep_outermost(markers)
