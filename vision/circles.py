"""Sub-pixel centres of round marks, holes and spheres.

Two refinements of a threshold blob are provided:

* ``method="fit"`` (default): least-squares fit of a blurred elliptical disk,
  ``I = (bg + amp * erfc(R0 (rho - 1) / (s sqrt 2)) / 2) * (1 + gx x' + gy y')``
  with ``rho = sqrt(q^T M q)``, ``q = (x - cx, y - cy)`` and a linear
  illumination gradient (marks of radius >= 8 px), over an edge band.
  Centrally symmetric, so it returns the centre of the imaged ellipse.
* ``method="centroid"``: background-subtracted intensity-weighted centroid on an
  elliptical window, iterated so the window is centred.

Both reach a few thousandths of a pixel at sigma = 2 grey levels (see
``benchmarks/bench_markers.py``), against about 0.05 px for a binary centroid
or an ellipse fitted to a threshold contour.

Pixel convention: x right, y down, centre of the top-left pixel at (0, 0).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinid.errors import ImageError

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


def _det2(M):
    """Determinant of a 2 x 2 matrix (closed form: far cheaper than ``np.linalg.det`` on a tiny matrix)."""
    return float(M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0])


def _inv2(M):
    """Inverse of a 2 x 2 matrix with a non-zero determinant (closed form)."""
    return np.array([[M[1, 1], -M[0, 1]], [-M[1, 0], M[0, 0]]]) / _det2(M)


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


def fit_disk_model(img, x0, y0, M0, *, window_px=None, gradient=None, max_nfev=50, tol_px=1e-5):
    """Least-squares fit of a blurred elliptical disk around an initial guess.

    Parameters
    ----------
    img : numpy.ndarray
        Float grey image (H, W).
    x0, y0 : float
        Initial centre, pixels.
    M0 : array_like, shape (2, 2)
        Initial ellipse matrix: the disk is ``q^T M q <= 1``.
    window_px : float or None
        Pixels with ``-1.5 window_px <= R0 (rho - 1) <= window_px`` (``R0`` the
        geometric-mean radius) are used; default ``max(4, min(0.6 R0, 12))``.
    gradient : bool or None
        Fit a linear multiplicative illumination gradient (vignetting, uneven
        lighting). ``None``: only for marks of radius >= 8 px, where the window
        determines it well; on smaller marks it costs more precision than the
        gradient's bias.
    max_nfev : int
        Iteration limit of the Levenberg-Marquardt loop.
    tol_px : float
        Convergence: a centre step smaller than this, pixels.

    Returns
    -------
    dict
        ``ok``, ``x``, ``y``, ``M``, ``radius``, ``sigma``, ``s`` (edge blur, px),
        ``bg``, ``amp``, ``message``.
    """
    from scipy.special import erfc

    M0 = np.asarray(M0, float)
    det = _det2(M0)
    if not det > 0:
        return {"ok": False, "message": "degenerate initial ellipse"}
    R0 = det ** -0.25
    if window_px is None:
        window_px = max(4.0, min(0.6 * R0, 12.0))
    rho_out = 1.0 + window_px / R0
    # bounding box of the outer ellipse
    Minv = _inv2(M0)
    ex, ey = rho_out * np.sqrt(Minv[0, 0]), rho_out * np.sqrt(Minv[1, 1])
    h, w = img.shape
    xa, xb = int(np.floor(x0 - ex)), int(np.ceil(x0 + ex)) + 1
    ya, yb = int(np.floor(y0 - ey)), int(np.ceil(y0 + ey)) + 1
    if xa < 0 or ya < 0 or xb > w or yb > h:
        return {"ok": False, "message": "mark too close to the image border"}
    sub = img[ya:yb, xa:xb]
    qx = np.arange(xa, xb) - x0  # a row and a column broadcast over the box: no coordinate grids
    qy = (np.arange(ya, yb) - y0)[:, None]
    rho0 = (M0[0, 0] * qx * qx) + (2 * M0[0, 1] * qx) * qy
    rho0 += M0[1, 1] * qy * qy
    rho0 = np.sqrt(rho0, out=rho0)
    rho_in = max(0.0, 1.0 - 1.5 * window_px / R0)  # interior far from the edge carries no centre information
    iy, ix = np.nonzero((rho0 <= rho_out) & (rho0 >= rho_in))
    I = sub[iy, ix].astype(float)
    rs = rho0[iy, ix]
    inner = I[rs < 1.0 - 0.6 * (1.0 - rho_in)]
    outer = I[rs > 1.0 + 0.6 * (rho_out - 1.0)]
    if inner.size < 1 or outer.size < 4:
        return {"ok": False, "message": "window too small"}
    bg0 = float(np.median(outer))
    amp0 = float(np.median(inner)) - bg0
    sq2 = np.sqrt(2.0)
    rsqpi = 1.0 / np.sqrt(np.pi)
    if gradient is None:
        gradient = R0 >= 8.0
    npar = 10 if gradient else 8
    X = ix + (xa - x0)  # coordinates relative to the start
    Y = iy + (ya - y0)
    Xr, Yr = X / R0, Y / R0  # for the illumination gradient
    N = X.size
    # the Jacobian, one row per parameter (contiguous rows: fast to fill and multiply); two buffers, the
    # current point's and a trial step's
    J, J_new = np.empty((npar, N)), np.empty((npar, N))
    buf = np.empty((8, N))  # work arrays of evaluate (no new arrays per call)

    def evaluate(p, J):
        """Residuals at ``p``, the Jacobian written into ``J``."""
        cx, cy, a11, a12, a22, bg, amp, ls, gx, gy = p.tolist()
        qx, qy, ax, ay, rho, u, g, e = buf
        c = R0 / (np.exp(ls) * sq2)
        np.subtract(X, cx - x0, out=qx)
        np.subtract(Y, cy - y0, out=qy)
        np.multiply(qx, a11, out=ax)
        np.multiply(qy, a12, out=e)
        np.add(ax, e, out=ax)  # (M q)_x
        np.multiply(qx, a12, out=ay)
        np.multiply(qy, a22, out=e)
        np.add(ay, e, out=ay)  # (M q)_y
        np.multiply(qx, ax, out=rho)
        np.multiply(qy, ay, out=e)
        np.add(rho, e, out=rho)  # q^T M q
        np.maximum(rho, 1e-12, out=rho)
        np.sqrt(rho, out=rho)
        np.subtract(rho, 1.0, out=u)
        np.multiply(u, c, out=u)
        erfc(u, out=g)
        np.multiply(g, 0.5, out=g)
        base = g * amp
        base += bg
        if gradient:  # multiplicative illumination (vignetting, uneven lighting)
            L = gx * Xr
            L += gy * Yr
            L += 1.0
            r = base * L
        else:
            L = 1.0
            r = base.copy()
        r -= I
        np.square(u, out=e)
        np.negative(e, out=e)
        np.exp(e, out=e)  # exp(-u^2); dg/du = -exp(-u^2) / sqrt(pi)
        nk = J[5]  # -(dI/drho) / rho, kept in the row of d/d(bg) until that is written
        np.multiply(e, amp * c * rsqpi, out=nk)
        if gradient:
            np.multiply(nk, L, out=nk)
        np.divide(nk, rho, out=nk)
        np.multiply(nk, ax, out=J[0])  # d/d(cx) = -(dI/drho) (M q)_x / rho
        np.multiply(nk, ay, out=J[1])
        np.multiply(nk, -0.5, out=rho)  # k / 2 (rho is no longer needed)
        np.multiply(rho, qx, out=J[3])
        np.multiply(J[3], qx, out=J[2])  # d/d(a11) = k qx^2 / 2
        np.multiply(J[3], qy, out=J[3])
        np.multiply(J[3], 2.0, out=J[3])  # d/d(a12) = k qx qy
        np.multiply(rho, qy, out=J[4])
        np.multiply(J[4], qy, out=J[4])  # d/d(a22) = k qy^2 / 2
        J[5] = L  # d/d(bg)
        np.multiply(g, L, out=J[6])  # d/d(amp)
        np.multiply(e, u, out=J[7])
        np.multiply(J[7], amp * rsqpi, out=J[7])  # d/d(log s)
        if gradient:
            np.multiply(J[7], L, out=J[7])
            np.multiply(base, Xr, out=J[8])
            np.multiply(base, Yr, out=J[9])
        return r

    def normal(J, r):  # the normal matrix and the gradient
        return J @ J.T, J @ r

    def sumsq(r):
        return float(r @ r)

    p = np.array([x0, y0, M0[0, 0], M0[0, 1], M0[1, 1], bg0, amp0, np.log(1.0), 0.0, 0.0])
    # Levenberg-Marquardt (small dense problem: a plain loop beats a general solver's overhead)
    r = evaluate(p, J)
    cost = sumsq(r)
    A, gv = normal(J, r)
    lam = 1e-3
    converged = False
    message = "iteration limit reached"
    for _ in range(int(max_nfev)):
        D = np.diag(np.maximum(np.diag(A), 1e-12))
        try:
            step = -np.linalg.solve(A + lam * D, gv)
        except np.linalg.LinAlgError:
            lam *= 10.0
            continue
        p_new = p.copy()
        p_new[:npar] += step
        if lam <= 1e-2 and abs(step[0]) < tol_px and abs(step[1]) < tol_px:
            # a Gauss-Newton step (little damping) that moves the centre by less than the tolerance:
            # converged; the step is taken without evaluating the model once more
            p = p_new
            converged, message = True, ""
            break
        r_new = evaluate(p_new, J_new)
        cost_new = sumsq(r_new)
        if np.isfinite(cost_new) and cost_new <= cost:
            p, r, cost = p_new, r_new, cost_new
            J, J_new = J_new, J
            A, gv = normal(J, r)
            lam = max(lam / 3.0, 1e-9)
        else:
            lam *= 4.0
            if lam > 1e8:  # no further decrease possible: at a minimum to numerical precision
                converged, message = True, ""
                break
    M = np.array([[p[2], p[3]], [p[3], p[4]]])
    detM = _det2(M)
    if not (detM > 0 and M[0, 0] > 0):
        return {"ok": False, "message": "fit diverged (ellipse not positive definite)"}
    dof = max(N - npar, 1)
    s2 = cost / dof
    try:
        try:  # the centre's two columns of the inverse normal matrix
            cov = np.linalg.solve(A, np.eye(npar)[:, :2]) * s2
        except np.linalg.LinAlgError:  # singular: the pseudo-inverse
            cov = np.linalg.pinv(A) * s2
        sigma = float(np.sqrt(max(0.5 * (cov[0, 0] + cov[1, 1]), 0.0)))
    except np.linalg.LinAlgError:  # pragma: no cover
        sigma = float("nan")
    ok = converged and abs(p[0] - x0) < R0 and abs(p[1] - y0) < R0 and abs(p[6]) > 0
    return {"ok": ok, "x": float(p[0]), "y": float(p[1]), "M": M, "radius": float(detM ** -0.25),
            "sigma": sigma, "s": float(np.exp(p[7])), "bg": float(p[5]), "amp": float(p[6]),
            "rms": float(np.sqrt(s2)), "message": "" if ok else f"fit did not converge ({message})"}


def weighted_centroid(img, x0, y0, M0, bg, ink, *, window_px=None, iterations=3):
    """Background-subtracted intensity-weighted centroid on an elliptical window.

    Weights ``(I - bg) / (ink - bg)`` (not clipped, so noise averages out) on
    pixels with ``R0 (rho - 1) <= window_px``; the window is re-centred on the
    estimate ``iterations`` times. Returns ``(x, y)`` or ``None`` if the window
    leaves the image.
    """
    M0 = np.asarray(M0, float)
    R0 = np.linalg.det(M0) ** -0.25
    if window_px is None:
        window_px = max(4.0, min(0.6 * R0, 12.0))
    rho_out = 1.0 + window_px / R0
    Minv = np.linalg.inv(M0)
    ex, ey = rho_out * np.sqrt(Minv[0, 0]) + 1, rho_out * np.sqrt(Minv[1, 1]) + 1
    h, w = img.shape
    x, y = float(x0), float(y0)
    for _ in range(iterations):
        xa, xb = int(np.floor(x - ex)), int(np.ceil(x + ex)) + 1
        ya, yb = int(np.floor(y - ey)), int(np.ceil(y + ey)) + 1
        if xa < 0 or ya < 0 or xb > w or yb > h:
            return None
        ys, xs = np.mgrid[ya:yb, xa:xb]
        qx, qy = xs - x, ys - y
        rho = np.sqrt(M0[0, 0] * qx * qx + 2 * M0[0, 1] * qx * qy + M0[1, 1] * qy * qy)
        wgt = (img[ya:yb, xa:xb] - bg) / (ink - bg)
        wgt = np.where(rho <= rho_out, wgt, 0.0)
        tot = wgt.sum()
        if not tot > 0:
            return None
        x, y = float((wgt * xs).sum() / tot), float((wgt * ys).sum() / tot)
    return x, y


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
