"""Reading one ring-coded mark: its code from the ring around a centre circle, and its centre refined.

The candidate search that finds centre circles in an image is :mod:`vision.ringcode`; this module reads
what it found (docs/vision_markers.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..disk_fit import _det2, _inv2, _median, fit_disk_model, weighted_centroid

__all__ = ["Marker", "canonical_code", "decode_from_segments", "read_ring"]


@dataclass(frozen=True)
class Marker:
    """A decoded ring-coded mark.

    Attributes
    ----------
    code : int
        Canonical code (smallest cyclic rotation).
    x_px, y_px : float
        Centre of the centre circle, pixels.
    radius_px : float
        Radius of the centre circle (geometric mean of its semi-axes), pixels.
    bits : str
        The bits of ``code`` as a string of length n, MSB first.
    """

    code: int
    x_px: float
    y_px: float
    radius_px: float
    bits: str


_CANONICAL = {}  # (value, n) -> canonical code, filled by canonical_code


def canonical_code(bits_value: int, n=12) -> int:
    """Smallest value over the ``n`` cyclic rotations of an ``n``-bit value.

    Examples
    --------
    >>> canonical_code(0b110001110000)
    199
    """
    n = int(n)
    v = int(bits_value)
    if not 0 <= v < (1 << n):
        raise ValueError(f"bits_value must be in 0..{(1 << n) - 1} for n={n}, got {bits_value}")
    key = (v, n)
    best = _CANONICAL.get(key)
    if best is not None:
        return best
    mask = (1 << n) - 1
    best = v
    for _ in range(n - 1):
        v = ((v << 1) | (v >> (n - 1))) & mask
        best = min(best, v)
    if len(_CANONICAL) < 1 << 16:  # bounded: the codes of 16-bit rings at most
        _CANONICAL[key] = best
    return best


def decode_from_segments(segment_elements, gap_angles_deg, n=12) -> int:
    """Decode a mark from its printed segments, as in the monocular contour method (formulas 4-5).

    Parameters
    ----------
    segment_elements : sequence of int
        ``M_i``: elements in each printed ring segment, in clockwise order
        (``m_i = round(A_i / a)`` from segment area ``A_i`` and element area ``a``).
    gap_angles_deg : sequence of float
        ``theta_i``: angle, seen from the centre circle's centroid, from the
        centroid of segment i clockwise to that of segment i+1 (the last one
        back to the first), degrees.
    n : int
        Number of ring elements.

    Returns
    -------
    int
        The canonical code. The blank elements between segments i and i+1 are
        ``q_i = round(theta_i n / 360 - (M_i + M_{i+1}) / 2)``.

    Examples
    --------
    The patent's worked example: segments of 3 and 2 elements at 195 and 165
    degrees give gaps of 4 and 3 and the code 000011000111:

    >>> decode_from_segments([3, 2], [195, 165])
    199
    """
    m = [int(v) for v in segment_elements]
    th = [float(v) for v in gap_angles_deg]
    n = int(n)
    if len(m) != len(th) or not m:
        raise ValueError(f"need one gap angle per segment, got {len(m)} segments and {len(th)} angles")
    if any(v < 1 for v in m):
        raise ValueError(f"segment element counts must be >= 1, got {m}")
    bits = []
    for i, mi in enumerate(m):
        mj = m[(i + 1) % len(m)]
        q = int(round(th[i] * n / 360.0 - (mi + mj) / 2.0))
        if q < 1 and len(m) > 1:
            raise ValueError(f"gap {i} has {q} elements (angle {th[i]} deg); segments must be separated")
        bits += [1] * mi + [0] * max(q, 0)
    if len(bits) != n:
        raise ValueError(f"segments and gaps add up to {len(bits)} elements, expected {n}")
    value = int("".join(map(str, bits)), 2)
    return canonical_code(value, n)


# ---------------------------------------------------------------------------
# detection

#: Ring geometry relative to the centre-circle radius (patent: Ø5 centre, Ø9-Ø13 ring).
_RHO_MIN, _RHO_MAX = 1.2, 3.2


def _sqrt_inv(M):
    """Symmetric M^(-1/2) of a 2x2 symmetric positive definite matrix."""
    a, b, c = float(M[0, 0]), float(M[0, 1]), float(M[1, 1])
    dm = a * c - b * b
    if not (dm > 0 and a > 0):  # not positive definite: as the eigen-decomposition gives it
        w, V = np.linalg.eigh(M)
        return (V / np.sqrt(w)) @ V.T
    # sqrt(M) = (M + sqrt(det M) I) / sqrt(tr M + 2 sqrt(det M)), whose determinant is sqrt(det M)
    sd = np.sqrt(dm)
    k = 1.0 / (np.sqrt(a + c + 2.0 * sd) * sd)
    return np.array([[(c + sd) * k, -b * k], [-b * k, (a + sd) * k]])


def read_ring(img, x, y, M, bg, ink, n=12, *, n_angles=None, band=None):
    """Read the bits of the ring around a centre circle ``q^T M q <= 1`` at (x, y).

    Parameters
    ----------
    img : numpy.ndarray
        Float grey image, full resolution.
    x, y : float
        Centre-circle centre, pixels.
    M : array_like, shape (2, 2)
        Centre-circle ellipse matrix.
    bg, ink : float
        Background and ink grey levels.
    n : int
        Ring elements.
    n_angles : int or None
        Angular samples; default ``max(360, 30 n)``.
    band : tuple of float or None
        Known (inner, outer) ring radii in centre radii (from an earlier read): only the band is
        sampled, the radial search and the gap check are skipped.

    Returns
    -------
    tuple
        ``(value, "", (inner, outer))``: the n-bit value read clockwise from the
        element phase origin (MSB first) and the ring band in centre radii, or
        ``(None, reason, None)`` when the ring cannot be read with confidence.
    """
    import cv2

    if n_angles is None:
        n_angles = max(360, 30 * n)
    A = _sqrt_inv(np.asarray(M, float))  # unit circle -> centre ellipse
    R = _det2(A) ** 0.5
    if band is None:
        step = max(0.5 / R, 0.04)  # half-pixel radial steps, at most 50 rows
        rho = np.arange(_RHO_MIN, _RHO_MAX, step)
    else:
        rho = np.linspace(band[0], band[1], min(16, max(5, int(np.ceil((band[1] - band[0]) * R)) + 1)))
    d = A @ _unit_rays(n_angles)  # (2, n_angles)
    # the sample points as one two-channel map (n_rho, n_angles, 2): x + rho d_x, y + rho d_y
    xy = rho[:, None, None] * d.T[None, :, :]
    xy += (x, y)
    xy = xy.astype(np.float32)
    mx, my = xy[..., 0], xy[..., 1]
    P = cv2.remap(img, xy, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=float("nan"))
    h, w = img.shape
    # every sample (and its interpolation neighbours) inside the image and a number: none is missing
    # (the samples' extent bounded first from the ellipse: no pass over them when far from the border)
    rmax = max(abs(rho[0]), abs(rho[-1]))
    ex, ey = rmax * np.abs(d[0]).max() + 0.01, rmax * np.abs(d[1]).max() + 0.01
    if ex <= x <= w - 2 - ex and ey <= y <= h - 2 - ey:
        all_in = not np.isnan(P).any()
    else:
        all_in = (mx.min() >= 0 and my.min() >= 0 and mx.max() <= w - 2 and my.max() <= h - 2
                  and not np.isnan(P).any())
    if not all_in:
        outside = ~((mx >= 0) & (my >= 0) & (mx <= w - 1) & (my <= h - 1))
        P[outside] = np.nan
    if band is not None:
        W = (P - bg) / (ink - bg)  # ink fraction, (n_rho, n_angles)
        if not (all_in or not np.isnan(W).any()):
            return None, "ring cut by the image border", None
        return (*_read_profile(_band_profile(W), n, n_angles), tuple(band))
    # inked fraction of each radius: the samples beyond the level midway between background and ink
    # (ink fraction > 0.5) counted on the grey levels, without the ink-fraction array of all samples
    mid = bg + 0.5 * (ink - bg)
    if all_in:
        valid = None
        # counted as bytes (a boolean sum goes through int64)
        f = np.add.reduce((P > mid if ink > bg else P < mid).view(np.uint8), axis=1, dtype=np.int32) / n_angles
    else:
        valid = ~np.isnan(P)
        f = (np.nan_to_num(P, nan=bg) > mid if ink > bg else np.nan_to_num(P, nan=bg) < mid).sum(axis=1)
        f = f / np.maximum(valid.sum(axis=1), 1)
    fmax = f.max()
    if fmax < 0.5 / n:
        return None, "no ring around the centre circle", None
    # the band: the run of radii around the most inked one (ink further out, e.g. a neighbour's
    # ring on a tight board, is not part of it)
    strong = f > 0.5 * fmax
    i0 = i1 = int(np.argmax(f))
    while i0 > 0 and strong[i0 - 1]:
        i0 -= 1
    while i1 < len(f) - 1 and strong[i1 + 1]:
        i1 += 1
    r_in, r_out = rho[i0], rho[i1]
    if not (1.4 < r_in < 2.3 and 2.1 < r_out < 3.2 and r_out - r_in > 0.35):
        return None, f"ring band {r_in:.2f}-{r_out:.2f} (centre radii) is not where a ring belongs", None
    if not (all_in or valid[rho <= r_out + 2.0 / R].all()):
        return None, "ring cut by the image border", None
    # the gap between centre circle and ring must be empty
    # (away from both blurred edges; at least one clean circle must separate them)
    margin = max(0.1, 1.5 / R)
    inside = (rho > 1.0 + margin) & (rho < r_in - margin)
    if np.any(inside) and ((P[inside] - bg) / (ink - bg)).mean(axis=1).min() > 0.15:
        return None, "ink between the centre circle and the ring", None
    in_band = (rho >= r_in) & (rho <= r_out)
    value, reason = _read_profile(_band_profile((P[in_band] - bg) / (ink - bg)), n, n_angles)
    return value, reason, ((float(r_in), float(r_out)) if value is not None else None)


_RAYS = {}


def _unit_rays(n_angles):
    """Unit vectors (2, n_angles) at the angles (k + 0.5) 2 pi / n_angles (cached)."""
    u = _RAYS.get(n_angles)
    if u is None:
        th = (np.arange(n_angles) + 0.5) * (2 * np.pi / n_angles)
        u = _RAYS[n_angles] = np.stack([np.cos(th), np.sin(th)])
        u.flags.writeable = False
    return u


def _band_profile(Wb):
    """Angular ink profile of a ring band: per angle, the largest ink of a 3-row running mean.

    The maximum over the band (rather than the mean of its core) keeps a printed element at
    full ink where perspective shifts the ring radially against the centre circle's ellipse.
    """
    if Wb.shape[0] >= 3:
        Wb = (Wb[:-2] + Wb[1:-1] + Wb[2:]) / 3.0
    return Wb.max(axis=0)


_WEIGHTS = {}


def _bit_weights(n):
    """Place values of n bits, most significant first (cached)."""
    wts = _WEIGHTS.get(n)
    if wts is None:
        wts = _WEIGHTS[n] = 1 << np.arange(n - 1, -1, -1, dtype=np.int64)
        wts.flags.writeable = False
    return wts


def _read_profile(prof, n, n_angles):
    """Bits from an angular ink profile (clockwise as seen in the image): ``(value, "")`` or ``(None, reason)``."""
    # element phase from the edges of the profile
    b = prof > 0.5
    change = np.empty(b.size, bool)  # b differs from its predecessor (cyclic)
    np.not_equal(b[1:], b[:-1], out=change[1:])
    change[0] = b[0] != b[-1]
    edges = np.flatnonzero(change)
    if edges.size == 0:
        return None, "ring has no element boundaries"
    # sub-sample edge position: linear interpolation of the 0.5 crossing
    p0, p1 = prof[edges - 1], prof[edges]  # index -1: the last sample
    d = p1 - p0
    d[d == 0] = 1.0
    frac = np.minimum(np.maximum((0.5 - p0) / d, 0.0), 1.0)  # clipped to [0, 1]
    t_edge = (edges - 1 + frac + 0.5) * (2 * np.pi / n_angles)  # angle of the crossing
    z = np.exp(1j * n * t_edge)
    zm = complex(np.add.reduce(z)) / z.size  # the mean (np.add.reduce: the same sum, less overhead)
    if abs(zm) < 0.9:
        return None, "ring edges do not fall on an element grid"
    phase = np.arctan2(zm.imag, zm.real) / n  # element boundaries at phase + k 2pi/n
    per = n_angles / n
    m = int(0.6 * per)
    a0 = phase + (np.arange(n) + 0.2) * (2 * np.pi / n)  # the central 60 % of each element
    idx = (np.floor(a0 / (2 * np.pi) * n_angles)[:, None].astype(int) + np.arange(m)) % n_angles
    v = np.add.reduce(prof[idx], axis=1) / m  # each element's mean ink
    unclear = np.flatnonzero((v > 0.25) & (v < 0.75))
    if unclear.size:
        k = int(unclear[0])
        return None, f"element {k} is neither printed nor blank (ink {v[k]:.2f})"
    value = int((v >= 0.75) @ _bit_weights(n))
    if value == 0 or value == (1 << n) - 1:
        return None, "ring is uniform"
    return value, ""


def _refine_moments(img, X, Y, M, bg, ink, iterations=2):
    """Centre and ellipse of the centre circle from grey-level moments (ink fraction clipped to [0, 1]).

    Uses the pixels within 1.4 radii of the current ellipse (the ring starts at 1.8), so the
    result is far better than the moments of a thresholded, downsampled blob. Returns
    ``(x, y, M)`` or None when the window leaves the image or holds no ink.
    """
    import cv2

    h, w = img.shape
    for _ in range(iterations):
        Minv = _inv2(M)
        ex, ey = 1.4 * np.sqrt(Minv[0, 0]) + 1, 1.4 * np.sqrt(Minv[1, 1]) + 1
        xa, xb = int(np.floor(X - ex)), int(np.ceil(X + ex)) + 1
        ya, yb = int(np.floor(Y - ey)), int(np.ceil(Y + ey)) + 1
        if xa < 0 or ya < 0 or xb > w or yb > h:
            return None
        qx = (np.arange(xa, xb) - X)[None, :]  # broadcast over the window: no coordinate grids
        qy = (np.arange(ya, yb) - Y)[:, None]
        outwin = (M[0, 0] * qx * qx + 2 * M[0, 1] * qx * qy + M[1, 1] * qy * qy) > 1.96
        wgt = np.subtract(img[ya:yb, xa:xb], bg, dtype=np.float32)
        wgt *= np.float32(1.0 / (ink - bg))
        np.maximum(wgt, 0.0, out=wgt)  # the ink fraction clipped to [0, 1] (np.clip's wrapper costs more)
        np.minimum(wgt, 1.0, out=wgt)
        wgt[outwin] = 0.0
        mo = cv2.moments(wgt)  # sums in double precision
        tot = mo["m00"]
        if not tot > 3:
            return None
        X = xa + mo["m10"] / tot
        Y = ya + mo["m01"] / tot
        cov = np.array([[mo["mu20"], mo["mu11"]], [mo["mu11"], mo["mu02"]]]) / tot
        if not _det2(cov) > 0:
            return None
        M = _inv2(4 * cov)
    return X, Y, M


def _local_levels(img, X, Y, M, sign):
    """Background and ink grey levels around one candidate (robust medians)."""
    A = _sqrt_inv(M)
    R = np.sqrt(_det2(A))
    h, w = img.shape
    d = A @ _UNIT_64
    # pixels at 0, 0.3, 0.5 radii (ink) and 1.4, 1.5 radii (background) on 64 rays
    xi = np.rint(X + _LEVEL_RADII[:, None] * d[0]).astype(int)
    yi = np.rint(Y + _LEVEL_RADII[:, None] * d[1]).astype(int)
    np.minimum(np.maximum(xi, 0, out=xi), w - 1, out=xi)  # clipped to the image
    np.minimum(np.maximum(yi, 0, out=yi), h - 1, out=yi)
    v = img[yi, xi]
    ink = float(_median(v[:3].ravel()))
    bg = float(_median(v[3:].ravel()))
    if R < 1 or (ink - bg) * sign <= 0:
        return None
    return bg, ink


_UNIT_64 = np.stack([np.cos(np.linspace(0, 2 * np.pi, 64, endpoint=False)),
                     np.sin(np.linspace(0, 2 * np.pi, 64, endpoint=False))])
_LEVEL_RADII = np.array([0.0, 0.3, 0.5, 1.4, 1.5])


#: Marks are decoded and refined on a box-filtered copy in which the centre radius is about this (px).
_WORK_RADIUS_PX = 30.0

#: Outer half-width of the edge band used by the centre refinement, work pixels.
_WINDOW_PX = 6.0

#: Convergence of the centre refinement: a centre step under this, work pixels (the fit converges
#: about linearly near its end, ~0.15 per step: the centre is then within ~2e-4 px of the limit, a
#: tenth of the noise-limited accuracy, at one model evaluation less than 1e-5 needs).
_FIT_TOL_PX = 1e-4


def _decode_one(img, X, Y, M, sign, n, refine, scale=1, clockwise=True):
    """Decode and refine one candidate (full-resolution guess X, Y, M); returns a Marker or None.

    ``scale`` is the factor of the level the candidate comes from; ``clockwise=False`` reports the
    bits read counter-clockwise (the bit mirror image of the clockwise reading).
    """
    import cv2

    R_full = _det2(M) ** -0.25
    f = max(1, int(R_full // _WORK_RADIUS_PX))
    # crop around the mark, aligned to the box size f; box filtering keeps the centre unbiased. The
    # margin allows for a candidate ellipse up to 20 % small (a blob thresholded on a coarse level).
    ext = 1.2 * _RHO_MAX * np.sqrt(_inv2(M).diagonal()) + 2 * f + 2
    h, w = img.shape
    x0, y0 = max(0, int(X - ext[0])), max(0, int(Y - ext[1]))
    x1, y1 = min(w, int(np.ceil(X + ext[0])) + 1), min(h, int(np.ceil(Y + ext[1])) + 1)
    x1 -= (x1 - x0) % f
    y1 -= (y1 - y0) % f
    if x1 - x0 < 3 * f or y1 - y0 < 3 * f:
        return None
    crop = img[y0:y1, x0:x1]
    if f == 2 and crop.dtype == np.uint8:
        # the 2 x 2 box average straight from 8 bits (sums of integers: exact, as INTER_AREA gives it),
        # without a float copy of the whole crop
        work = np.add(crop[0::2], crop[1::2], dtype=np.float32)
        work = np.add(work[:, 0::2], work[:, 1::2])
        work *= np.float32(0.25)
    elif f > 1:
        work = cv2.resize(crop.astype(np.float32), ((x1 - x0) // f, (y1 - y0) // f), interpolation=cv2.INTER_AREA)
    else:
        work = crop.astype(np.float32)
    Xw, Yw, Mw = (X - x0 + 0.5) / f - 0.5, (Y - y0 + 0.5) / f - 0.5, M * (f * f)
    # a crop clipped by the image border must still look like the border to read_ring: it does,
    # because the crop only ever stops short of the ring where the image itself ends.
    lv = _local_levels(work, Xw, Yw, Mw, sign)
    if lv is None:
        return None
    bg, ink = lv
    if abs(ink - bg) < 10:
        return None
    if R_full / scale < 15:  # a small thresholded blob gives a poor ellipse: use grey-level moments
        rough = _refine_moments(work, Xw, Yw, Mw, bg, ink)
        if rough is None:
            return None
        Xw, Yw, Mw = rough
    first = read_ring(work, Xw, Yw, Mw, bg, ink, n)
    if first[0] is None:
        return None
    value, band = first[0], first[2]
    R0 = _det2(Mw) ** -0.25
    # the ring's inner edge is at ~1.8 R: keep the window clear of it
    win = max(2.0, min(0.45 * R0, _WINDOW_PX))
    if refine == "fit":
        r = fit_disk_model(work, Xw, Yw, Mw, window_px=win, tol_px=_FIT_TOL_PX)
        if not r["ok"]:
            return None
        x, y, Mf = r["x"], r["y"], r["M"]
        if abs(r["amp"]) < 0.5 * abs(ink - bg) or np.hypot(x - Xw, y - Yw) > 0.5 * R0:
            return None
        # re-read the ring with the refined ellipse: must agree
        k = R0 / r["radius"]  # the band was measured in radii of the rough (threshold) ellipse
        value2 = read_ring(work, x, y, Mf, r["bg"], r["bg"] + r["amp"], n, band=(band[0] * k, band[1] * k))[0]
        if value2 is None or canonical_code(value2, n) != canonical_code(value, n):
            return None
        radius = r["radius"]
    else:
        xy = weighted_centroid(work, Xw, Yw, Mw, bg, ink, window_px=win)
        if xy is None:
            return None
        x, y = xy
        radius = float(R0)
    if not clockwise:
        value = int(format(value, f"0{n}b")[::-1], 2)
    code = canonical_code(value, n)
    return Marker(int(code), float((x + 0.5) * f - 0.5 + x0), float((y + 0.5) * f - 0.5 + y0), float(radius * f),
                  format(code, f"0{n}b"))
