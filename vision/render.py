"""Anti-aliased rendering of printed patterns (round fiducials, ring-coded marks, boards).

A pattern is a *coverage* function of plane points (mm): 1 where ink is
printed, 0 elsewhere. :func:`render_pattern` samples it through an inverse
camera mapping ``image_to_plane`` (pixel -> plane mm), so any pose, homography
or lens distortion composes by writing that one function.

Pixel convention (OpenCV): x right, y down, the centre of the top-left pixel at
(0, 0); a pixel covers ``[x - 0.5, x + 0.5] x [y - 0.5, y + 0.5]``.

Plane convention for ring-coded marks (docs/formats.md, "Board file"): plane x right,
y down as seen by the camera with the board unrotated; the ring's elements are
numbered clockwise as seen in the image, element 0 (the most significant bit)
starting at ``angle_deg`` from the plane x axis.
"""
from __future__ import annotations

import numpy as np

__all__ = [
    "render_pattern",
    "homography_image_to_plane",
    "similarity_plane_to_image",
    "disk_coverage",
    "ring_mark_coverage",
    "board_coverage",
    "render_disk",
]


def _check_shape(image_shape):
    from kinid.errors import DataError

    try:
        h, w = (int(v) for v in image_shape[:2])
    except (TypeError, ValueError):
        raise DataError(f"must be (height, width), got {image_shape!r}", parameter="image_shape") from None
    if h < 1 or w < 1:
        raise DataError(f"must be positive (height, width), got {image_shape!r}", parameter="image_shape")
    return h, w


def render_pattern(coverage, image_shape, image_to_plane, *, low=30, high=220, supersample=4,
                   blur_px=0.0, noise_sigma=0.0, rng=None) -> np.ndarray:
    """Render a printed pattern as an 8-bit grey image.

    Parameters
    ----------
    coverage : callable
        ``coverage(xy_mm) -> (N,)`` with ``xy_mm`` of shape (N, 2), plane mm;
        returns ink coverage in [0, 1] (1 where printed).
    image_shape : tuple of int
        (height, width) of the image in pixels.
    image_to_plane : callable
        ``image_to_plane(xy_px) -> (N, 2)`` maps pixel positions (N, 2) to plane
        mm (the inverse of the camera mapping, so lens distortion composes).
    low, high : float
        Grey level of ink and of background (ink is dark by default; pass
        ``low > high`` for light marks on a dark background).
    supersample : int
        Sub-samples per pixel side; the pixel value uses the mean coverage of
        ``supersample**2`` sub-samples at cell centres.
    blur_px : float
        Standard deviation in pixels of a Gaussian blur applied after sampling
        (0: none).
    noise_sigma : float
        Standard deviation of additive Gaussian noise in grey levels.
    rng : numpy.random.Generator or None
        Noise generator; ``None`` uses a fresh ``np.random.default_rng()``.

    Returns
    -------
    numpy.ndarray
        uint8 image of shape (height, width).

    Notes
    -----
    Sampling is adaptive: coverage is first evaluated at pixel centres and only
    pixels whose 3 x 3 neighbourhood is not uniformly 0 or 1 are supersampled.
    This is exact for edges whose radius of curvature is large against a pixel
    (a straight edge that crosses a pixel always separates its centre from one
    of the 8 neighbours' centres); features thinner than a pixel that fall
    between pixel centres may be missed. Pixels on the image border are always
    supersampled.
    """
    from kinid.errors import DataError

    h, w = _check_shape(image_shape)
    for name, f in (("coverage", coverage), ("image_to_plane", image_to_plane)):
        if not callable(f):
            raise DataError(f"must be a function of (N, 2) points, got {type(f).__name__}", parameter=name)
    s = int(supersample)
    if s < 1:
        raise ValueError(f"supersample must be >= 1, got {supersample!r}")
    ys, xs = np.mgrid[0:h, 0:w]
    pix = np.column_stack([xs.ravel(), ys.ravel()]).astype(float)
    cov0 = np.asarray(coverage(np.asarray(image_to_plane(pix), float)), float).reshape(h, w)
    cov = cov0.copy()
    if s > 1:
        import cv2

        inked = (cov0 >= 1.0).astype(np.uint8)
        blank = (cov0 <= 0.0).astype(np.uint8)
        kernel = np.ones((3, 3), np.uint8)
        uniform = (cv2.erode(inked, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0) > 0) | (
            cv2.erode(blank, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0) > 0)
        idx = np.flatnonzero(~uniform.ravel())
        if idx.size:
            offs = (np.arange(s) + 0.5) / s - 0.5
            acc = np.zeros(idx.size)
            base = pix[idx]
            for oy in offs:
                for ox in offs:
                    acc += np.asarray(coverage(np.asarray(image_to_plane(base + (ox, oy)), float)), float)
            cov.ravel()[idx] = acc / (s * s)
    img = high + (low - high) * np.clip(cov, 0.0, 1.0)
    img = img.astype(np.float32)
    if blur_px and blur_px > 0:
        import cv2

        k = int(2 * np.ceil(4 * blur_px) + 1)
        img = cv2.GaussianBlur(img, (k, k), sigmaX=float(blur_px), sigmaY=float(blur_px),
                               borderType=cv2.BORDER_REPLICATE)
    if noise_sigma and noise_sigma > 0:
        if rng is None:
            rng = np.random.default_rng()
        img = img + rng.normal(0.0, float(noise_sigma), img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def homography_image_to_plane(H_plane_to_image):
    """Inverse mapping (pixel -> plane mm) of a 3 x 3 plane-to-image homography.

    Parameters
    ----------
    H_plane_to_image : array_like, shape (3, 3)
        Maps homogeneous plane mm to homogeneous pixels.

    Returns
    -------
    callable
        ``f(xy_px: (N, 2)) -> (N, 2)`` plane mm.
    """
    H = np.asarray(H_plane_to_image, float)
    if H.shape != (3, 3):
        raise ValueError(f"H_plane_to_image must be 3x3, got shape {H.shape}")
    Hinv = np.linalg.inv(H)
    Hinv = Hinv / Hinv[2, 2] if Hinv[2, 2] != 0 else Hinv
    affine = Hinv[2, 0] == 0 and Hinv[2, 1] == 0 and Hinv[2, 2] == 1

    def image_to_plane(xy_px):
        xy = np.asarray(xy_px, float).reshape(-1, 2)
        x, y = xy[:, 0], xy[:, 1]
        u = Hinv[0, 0] * x + Hinv[0, 1] * y + Hinv[0, 2]
        v = Hinv[1, 0] * x + Hinv[1, 1] * y + Hinv[1, 2]
        if not affine:
            w = Hinv[2, 0] * x + Hinv[2, 1] * y + Hinv[2, 2]
            u /= w
            v /= w
        return np.column_stack([u, v])

    return image_to_plane


def similarity_plane_to_image(pixel_mm, angle_deg=0.0, offset_px=(0, 0)) -> np.ndarray:
    """3 x 3 homography of a camera looking straight down: plane mm -> pixels.

    ``px = R(angle) @ xy_mm / pixel_mm + offset_px`` with
    ``R = [[cos, -sin], [sin, cos]]`` in image axes (y down, so a positive
    angle turns the pattern clockwise as seen in the image).

    Parameters
    ----------
    pixel_mm : float
        Size of one pixel on the plane, mm per pixel.
    angle_deg : float
        In-plane rotation, degrees.
    offset_px : tuple of float
        Pixel position of the plane origin.
    """
    if not pixel_mm > 0:
        raise ValueError(f"pixel_mm must be positive, got {pixel_mm!r}")
    a = np.deg2rad(angle_deg)
    c, s = np.cos(a) / pixel_mm, np.sin(a) / pixel_mm
    return np.array([[c, -s, float(offset_px[0])], [s, c, float(offset_px[1])], [0.0, 0.0, 1.0]])


def disk_coverage(centre_mm, radius_mm):
    """Coverage of a filled disk.

    Parameters
    ----------
    centre_mm : tuple of float
        Disk centre on the plane, mm.
    radius_mm : float
        Disk radius, mm.
    """
    cx, cy = (float(v) for v in centre_mm)
    r2 = float(radius_mm) ** 2

    def coverage(xy_mm):
        xy = np.asarray(xy_mm, float)
        return (((xy[:, 0] - cx) ** 2 + (xy[:, 1] - cy) ** 2) <= r2).astype(float)

    return coverage


def _ring_test(dx, dy, bits_lookup, n, r_c2, r_i2, r_o2, angle_rad):
    """Ink test of a ring-coded mark at local offsets (dx, dy) mm.

    ``bits_lookup(element_index, mask) -> bool array`` gives the element bits
    for the points selected by ``mask``.
    """
    r2 = dx * dx + dy * dy
    ink = r2 <= r_c2
    band = (r2 >= r_i2) & (r2 <= r_o2)
    if np.any(band):
        ang = np.arctan2(dy[band], dx[band]) - angle_rad
        k = np.floor(np.mod(ang, 2 * np.pi) / (2 * np.pi / n)).astype(np.int64) % n
        ink[band] = bits_lookup(k, band)
    return ink


def _bit_array(code_bits: int, n: int) -> np.ndarray:
    """Element bits of a code, element 0 = most significant bit."""
    return np.array([(int(code_bits) >> (n - 1 - k)) & 1 for k in range(n)], bool)


def ring_mark_coverage(centre_mm, code_bits: int, bits=12, center_d_mm=5, ring_inner_d_mm=9,
                       ring_outer_d_mm=13, angle_deg=0.0):
    """Coverage of one ring-coded mark (the monocular contour method: centre circle + coded ring).

    Parameters
    ----------
    centre_mm : tuple of float
        Mark centre on the plane, mm.
    code_bits : int
        The n-bit pattern printed; element k (clockwise as seen in the image,
        starting at ``angle_deg``) is printed when bit ``n-1-k`` is set.
    bits : int
        Number of ring elements n.
    center_d_mm, ring_inner_d_mm, ring_outer_d_mm : float
        Diameters of the centre circle and of the ring's inner and outer edges, mm.
    angle_deg : float
        Start angle of element 0 from the plane x axis, degrees (clockwise as
        seen in the image, y down).
    """
    n = int(bits)
    cx, cy = (float(v) for v in centre_mm)
    barr = _bit_array(code_bits, n)
    rc2, ri2, ro2 = (float(center_d_mm) / 2) ** 2, (float(ring_inner_d_mm) / 2) ** 2, (float(ring_outer_d_mm) / 2) ** 2
    a = np.deg2rad(angle_deg)

    def coverage(xy_mm):
        xy = np.asarray(xy_mm, float)
        return _ring_test(xy[:, 0] - cx, xy[:, 1] - cy, lambda k, m: barr[k], n, rc2, ri2, ro2, a).astype(float)

    return coverage


def board_coverage(board):
    """Coverage of all marks of a :class:`vision.board.Board`, board-frame mm.

    Vectorised: each point is assigned to its nearest grid node by rounding and
    tested in that mark's local polar coordinates. Points outside the grid's
    marks are blank.
    """
    pitch = float(board.pitch_mm)
    rows, cols, n = int(board.rows), int(board.cols), int(board.bits)
    codes = np.asarray(board.codes, np.int64).reshape(rows, cols)
    shifts = (n - 1 - np.arange(n))
    bit_table = ((codes[..., None] >> shifts) & 1).astype(bool)  # (rows, cols, n)
    rc2 = (float(board.center_d_mm) / 2) ** 2
    ri2 = (float(board.ring_inner_d_mm) / 2) ** 2
    ro2 = (float(board.ring_outer_d_mm) / 2) ** 2
    if ro2 >= (pitch / 2) ** 2:
        raise ValueError("board marks overlap: ring_outer_d_mm must be smaller than pitch_mm")

    def coverage(xy_mm):
        xy = np.asarray(xy_mm, float)
        col = np.rint(xy[:, 0] / pitch).astype(np.int64)
        row = np.rint(xy[:, 1] / pitch).astype(np.int64)
        out = np.zeros(xy.shape[0])
        inside = (col >= 0) & (col < cols) & (row >= 0) & (row < rows)
        if not np.any(inside):
            return out
        sel = np.flatnonzero(inside)
        r_i, c_i = row[sel], col[sel]
        dx = xy[sel, 0] - c_i * pitch
        dy = xy[sel, 1] - r_i * pitch
        ink = _ring_test(dx, dy, lambda k, m: bit_table[r_i[m], c_i[m], k], n, rc2, ri2, ro2, 0.0)
        out[sel] = ink
        return out

    return coverage


def render_disk(image_shape, centre_px, radius_px, *, low=30, high=220, blur_px=0.8, noise_sigma=0.0,
                supersample=4, rng=None) -> np.ndarray:
    """Render one round fiducial directly in pixel coordinates.

    Parameters
    ----------
    image_shape : tuple of int
        (height, width), pixels.
    centre_px : tuple of float
        Disk centre (x, y), pixels.
    radius_px : float
        Disk radius, pixels.
    low, high, blur_px, noise_sigma, supersample, rng
        As in :func:`render_pattern`.

    Returns
    -------
    numpy.ndarray
        uint8 image of shape ``image_shape``.
    """
    return render_pattern(disk_coverage(centre_px, radius_px), image_shape, lambda xy: xy, low=low, high=high,
                          supersample=supersample, blur_px=blur_px, noise_sigma=noise_sigma, rng=rng)


# ---------------------------------------------------------------------------
# photographs of boards (perspective, uneven light, blur, JPEG): benchmarks and tests of the detector
