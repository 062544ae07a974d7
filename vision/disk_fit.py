"""Sub-pixel centre of one round mark by a model of its image: a blurred elliptical disk fitted by least
squares (:func:`fit_disk_model`), or an intensity-weighted centroid iterated on an elliptical window
(:func:`weighted_centroid`). :mod:`kinid.vision.circles` finds the marks and calls these.

* ``fit_disk_model``: ``I = (bg + amp * erfc(R0 (rho - 1) / (s sqrt 2)) / 2) * (1 + gx x' + gy y')``
  with ``rho = sqrt(q^T M q)``, ``q = (x - cx, y - cy)`` and a linear illumination gradient (marks of
  radius >= 8 px), over an edge band. Centrally symmetric, so it returns the centre of the imaged ellipse.
* ``weighted_centroid``: background-subtracted intensity-weighted centroid on an elliptical window,
  iterated so the window is centred.

Pixel convention: x right, y down, centre of the top-left pixel at (0, 0).
"""
from __future__ import annotations

import numpy as np

__all__ = ["fit_disk_model", "weighted_centroid"]

def _det2(M):
    """Determinant of a 2 x 2 matrix (closed form: far cheaper than ``np.linalg.det`` on a tiny matrix)."""
    return float(M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0])


def _median(v):
    """``np.median`` of a 1-D array, the same value (the mean of the two middle values in the array's
    dtype for an even count) without its general-purpose overhead (some 40 us a call)."""
    n = v.size
    k = n // 2
    if n % 2:
        return np.partition(v, k)[k]
    part = np.partition(v, (k - 1, k))
    return (part[k - 1] + part[k]) / 2


def _solve_spd(A, b):
    """Solution of ``A x = b`` for a symmetric positive definite A by Cholesky (LAPACK ``dposv``, called
    directly: a tenth of ``np.linalg.solve``'s overhead on a 10 x 10 system), or None if A is not."""
    from scipy.linalg.lapack import dposv

    _c, x, info = dposv(A, b)
    return x if info == 0 else None


def _inv2(M):
    """Inverse of a 2 x 2 matrix with a non-zero determinant (closed form)."""
    return np.array([[M[1, 1], -M[0, 1]], [-M[1, 0], M[0, 0]]]) / _det2(M)


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
    bg0 = float(_median(outer))
    amp0 = float(_median(inner)) - bg0
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
    diag = np.arange(npar) * (npar + 1)  # flat indices of the diagonal
    for _ in range(int(max_nfev)):
        # A + lam D with D = diag(A) (at least 1e-12): positive definite unless the model is degenerate
        AD = A.copy()
        AD.flat[diag] += lam * np.maximum(A.flat[diag], 1e-12)
        step = _solve_spd(AD, gv)
        if step is None:
            lam *= 10.0
            continue
        step = -step
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
        cov = _solve_spd(A, np.eye(npar)[:, :2])  # the centre's two columns of the inverse normal matrix
        if cov is None:
            try:
                cov = np.linalg.solve(A, np.eye(npar)[:, :2])
            except np.linalg.LinAlgError:  # singular: the pseudo-inverse
                cov = np.linalg.pinv(A)
        cov = cov * s2
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
