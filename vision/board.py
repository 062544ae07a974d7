"""Boards of ring-coded marks (the monocular contour method) and their description file (docs/formats.md, "Board file").

Board frame: origin at the centre of the mark in row 0, column 0; x along a
row (increasing column), y along a column (increasing row), as seen by the
camera with the board unrotated; millimetres.
"""
from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from kinid.errors import DataError
from kinid.files import read_json
from kinid.schema import Fields, Items, Number, validate

__all__ = ["Board", "BoardMatch", "make_board", "load_board", "save_board", "match_to_board", "board_codes"]


@dataclass(frozen=True)
class Board:
    """A rectangular grid of ring-coded marks.

    Attributes
    ----------
    pitch_mm : float
        Centre distance of neighbouring marks, mm.
    rows, cols : int
        Grid size.
    center_d_mm, ring_inner_d_mm, ring_outer_d_mm : float
        Diameters of each mark's centre circle and of its ring's edges, mm.
    bits : int
        Ring elements per mark.
    codes : tuple of tuple of int
        ``codes[row][col]``: the canonical code of each mark.
    """

    pitch_mm: float
    rows: int
    cols: int
    center_d_mm: float
    ring_inner_d_mm: float
    ring_outer_d_mm: float
    bits: int
    codes: tuple

    def mark_mm(self, row, col):
        """Board-frame position (x_mm, y_mm) of the mark at (row, col)."""
        return (float(col) * self.pitch_mm, float(row) * self.pitch_mm)

    def position_of(self, code):
        """(row, col) of the mark with this code, or None if the board has no such code."""
        return self._index().get(int(code))

    def _index(self):
        idx = self.__dict__.get("_code_index")
        if idx is None:
            idx = {int(c): (r, k) for r, row in enumerate(self.codes) for k, c in enumerate(row)}
            object.__setattr__(self, "_code_index", idx)
        return idx


@dataclass(frozen=True)
class BoardMatch:
    """A decoded marker assigned to a board position."""

    code: int
    row: int
    col: int
    x_px: float
    y_px: float


def _canonical(value: int, n: int) -> int:
    mask = (1 << n) - 1
    best = value
    v = value
    for _ in range(n - 1):
        v = ((v << 1) | (v >> (n - 1))) & mask
        best = min(best, v)
    return best


def board_codes(count: int, bits: int = 12) -> list:
    """Return ``count`` distinct canonical codes, increasing.

    Codes with no printed or no unprinted element are excluded (they cannot be
    decoded). Even-parity codes (pairwise Hamming distance >= 2 over all
    rotations) are preferred; odd-parity codes fill the rest when needed.
    """
    n = int(bits)
    classes = sorted({_canonical(v, n) for v in range(1, (1 << n) - 1)})
    even = [c for c in classes if bin(c).count("1") % 2 == 0]
    odd = [c for c in classes if bin(c).count("1") % 2 == 1]
    if count > len(classes):
        raise DataError(f"a board of {count} marks needs {count} distinct codes but {n}-bit rings give "
                        f"only {len(classes)}; use more bits or a smaller board", column="bits")
    chosen = even[:count] if count <= len(even) else even + odd[:count - len(even)]
    return sorted(chosen)


def make_board(rows=14, cols=14, pitch_mm=16.0, bits=12, center_d_mm=5.0, ring_inner_d_mm=9.0,
               ring_outer_d_mm=13.0) -> Board:
    """A board of ``rows x cols`` marks with distinct codes increasing left->right, top->bottom.

    Defaults are the patent's board: 14 x 14 marks, 16 mm pitch, 12-bit rings,
    centre Ø5 mm, ring Ø9-Ø13 mm.
    """
    from kinid.checks import check_int, check_positive

    rows, cols = check_int("rows", rows, minimum=1), check_int("cols", cols, minimum=1)
    bits = check_int("bits", bits, minimum=3, maximum=30)
    for name, v in (("pitch_mm", pitch_mm), ("center_d_mm", center_d_mm), ("ring_inner_d_mm", ring_inner_d_mm),
                    ("ring_outer_d_mm", ring_outer_d_mm)):
        check_positive(name, v)
    codes = board_codes(rows * cols, bits)
    grid = tuple(tuple(codes[r * cols:(r + 1) * cols]) for r in range(rows))
    board = Board(float(pitch_mm), rows, cols, float(center_d_mm), float(ring_inner_d_mm), float(ring_outer_d_mm),
                  int(bits), grid)
    _validate(board, None)
    return board


def _validate(board: Board, path):
    def bad(key, msg):
        raise DataError(msg, path=path, column=key)

    if not board.pitch_mm > 0:
        bad("pitch_mm", f"pitch_mm must be positive, got {board.pitch_mm}")
    if not 0 < board.center_d_mm < board.ring_inner_d_mm < board.ring_outer_d_mm:
        bad("ring_inner_d_mm", "diameters must satisfy 0 < center_d_mm < ring_inner_d_mm < ring_outer_d_mm, got "
            f"{board.center_d_mm}, {board.ring_inner_d_mm}, {board.ring_outer_d_mm}")
    if not board.ring_outer_d_mm < board.pitch_mm:
        bad("ring_outer_d_mm", f"ring_outer_d_mm ({board.ring_outer_d_mm}) must be smaller than pitch_mm "
            f"({board.pitch_mm}) or marks overlap")
    if not 3 <= board.bits <= 30:
        bad("bits", f"bits must be an integer in 3..30, got {board.bits}")
    seen = {}
    for r, row in enumerate(board.codes):
        for c, code in enumerate(row):
            if not 0 < code < (1 << board.bits) - 1:
                bad("codes", f"code {code} at row {r}, column {c} is not a decodable {board.bits}-bit code "
                    f"(expected 1..{(1 << board.bits) - 2})")
            if _canonical(code, board.bits) != code:
                bad("codes", f"code {code} at row {r}, column {c} is not canonical (smallest cyclic rotation "
                    f"is {_canonical(code, board.bits)})")
            if code in seen:
                bad("codes", f"code {code} appears twice: at row {seen[code][0]}, column {seen[code][1]} and at "
                    f"row {r}, column {c}")
            seen[code] = (r, c)


_KEYS = ("pitch_mm", "rows", "cols", "center_d_mm", "ring_inner_d_mm", "ring_outer_d_mm", "bits", "codes")
_SIZE_MM = Number(low=0, high=10000, open_low=True)
_COUNT = Number(low=1, high=10000, integer=True)
#: What a board file holds (docs/formats.md): sizes in mm up to 10 m, up to 10 000 rows and columns, codes of
#: up to 62 bits (how the codes fit the rings is checked after, with the board).
BOARD_SCHEMA = Fields({
    "pitch_mm": _SIZE_MM, "rows": _COUNT, "cols": _COUNT, "center_d_mm": _SIZE_MM, "ring_inner_d_mm": _SIZE_MM,
    "ring_outer_d_mm": _SIZE_MM, "bits": Number(low=1, high=62, integer=True),
    "codes": Items(Items(Number(low=0, high=2 ** 62, integer=True))),
}, other=True)


def load_board(path) -> Board:
    """Read a board description file (JSON, docs/formats.md).

    Raises
    ------
    DataError
        Naming the file and the key when the file is missing, not JSON, lacks
        a key or holds a bad value.
    """
    data = read_json(path, what="board file")
    if not isinstance(data, dict):
        raise DataError(f"expected a JSON object with keys {', '.join(_KEYS)}, got {type(data).__name__}", path=path)
    validate(data, BOARD_SCHEMA, path=path)
    rows, cols, bits = int(data["rows"]), int(data["cols"]), int(data["bits"])
    codes = data["codes"]
    if len(codes) != rows:
        raise DataError(f"expected a list of {rows} rows (key rows), got {len(codes)}", path=path, column="codes")
    for r, row in enumerate(codes):
        if len(row) != cols:
            raise DataError(f"row {r}: expected a list of {cols} codes (key cols), got {len(row)} codes", path=path,
                            column="codes")
    grid = tuple(tuple(int(v) for v in row) for row in codes)
    board = Board(float(data["pitch_mm"]), rows, cols, float(data["center_d_mm"]), float(data["ring_inner_d_mm"]),
                  float(data["ring_outer_d_mm"]), bits, grid)
    _validate(board, path)
    return board


def save_board(board: Board, path) -> None:
    """Write ``board`` as a board description file (JSON, docs/formats.md), atomically."""
    from kinid.files import write_text

    write_text(path, board_text(board))


def board_text(board: Board) -> str:
    """The board description file's text (JSON, docs/formats.md): one row of codes per line."""
    data = {"pitch_mm": board.pitch_mm, "rows": board.rows, "cols": board.cols, "center_d_mm": board.center_d_mm,
            "ring_inner_d_mm": board.ring_inner_d_mm, "ring_outer_d_mm": board.ring_outer_d_mm,
            "bits": board.bits, "codes": [list(map(int, row)) for row in board.codes]}
    lines = ",\n".join("    " + json.dumps(row) for row in data["codes"])
    head = json.dumps({k: v for k, v in data.items() if k != "codes"})[:-1]
    return head + ',\n  "codes": [\n' + lines + "\n  ]}\n"


def match_to_board(board: Board, markers, *, tolerance_pitch=0.3) -> list:
    """Assign decoded markers to board positions, rejecting geometrically inconsistent codes.

    Every marker whose code is on the board is a candidate. A similarity
    transform board -> image is hypothesised from each pair of image-neighbouring
    candidates (scale checked against the marker's centre-circle radius where
    known); the hypothesis that explains most candidates wins, a homography (or
    affine map) is refitted to its inliers, and only markers within
    ``tolerance_pitch`` pitches of their predicted image position are kept. A
    single-bit decoding error that yields another board code lands a whole
    pitch or more from where that code belongs and is rejected.

    Parameters
    ----------
    board : Board
    markers : sequence
        Objects with ``code``, ``x_px``, ``y_px`` (and optionally ``radius_px``,
        the centre-circle radius), e.g. :class:`vision.ringcode.Marker`.
    tolerance_pitch : float
        Accepted distance from the predicted position, in pitches.

    Returns
    -------
    list of BoardMatch
        In board order (row, then column). A lone marker (nothing to check it
        against) is returned as it is.
    """
    from kinid.checks import check_instance

    check_instance("board", board, Board, hint="load it with kinid.vision.load_board(path)")
    cand = []
    for m in markers:
        pos = board.position_of(int(m.code))
        if pos is not None:
            cand.append((m, pos))
    if not cand:
        return []
    # duplicate codes: keep all for now, geometry decides
    img = np.array([[float(m.x_px), float(m.y_px)] for m, _ in cand])
    brd = np.array([board.mark_mm(*pos) for _, pos in cand])
    rad = np.array([float(getattr(m, "radius_px", np.nan) or np.nan) for m, _ in cand])
    scale_hint = rad / (board.center_d_mm / 2.0)  # px per mm
    n = len(cand)
    if n == 1:
        m, (r, c) = cand[0]
        return [BoardMatch(int(m.code), r, c, float(m.x_px), float(m.y_px))]

    def similarity(i, j):
        db = brd[j] - brd[i]
        di = img[j] - img[i]
        zb, zi = complex(*db), complex(*di)
        if abs(zb) == 0:
            return None
        a = zi / zb
        return a, complex(*img[i]) - a * complex(*brd[i])

    # candidate pairs: each marker with its 4 nearest image neighbours
    d2 = ((img[:, None, :] - img[None, :, :]) ** 2).sum(-1)
    np.fill_diagonal(d2, np.inf)
    k = min(4, n - 1)
    nbrs = np.argsort(d2, axis=1)[:, :k]
    zb_all = brd[:, 0] + 1j * brd[:, 1]
    zi_all = img[:, 0] + 1j * img[:, 1]
    best, best_count, best_err = None, 0, np.inf
    for i in range(n):
        for j in nbrs[i]:
            s = similarity(i, int(j))
            if s is None:
                continue
            a, b = s
            hint = np.nanmedian(scale_hint[[i, int(j)]]) if np.any(np.isfinite(scale_hint[[i, int(j)]])) else np.nan
            if np.isfinite(hint) and not (0.75 < abs(a) / hint < 1.33):
                continue
            tol = tolerance_pitch * board.pitch_mm * abs(a)
            err = np.abs(a * zb_all + b - zi_all)
            inl = err < tol
            cnt = int(inl.sum())
            e = float(err[inl].sum() / max(cnt, 1)) / max(abs(a), 1e-12)
            if cnt > best_count or (cnt == best_count and e < best_err):
                best, best_count, best_err = (a, b), cnt, e
    if best is None or best_count < 2:
        return []
    a, b = best
    tol_px = tolerance_pitch * board.pitch_mm * abs(a)
    inl = np.abs(a * zb_all + b - zi_all) < tol_px
    # refine with a homography (>= 5 well spread inliers) or an affine map, then recheck
    for _ in range(2):
        idx = np.flatnonzero(inl)
        pred = _fit_predict(brd[idx], img[idx], brd)
        if pred is None:
            break
        inl_new = np.hypot(*(pred - img).T) < tol_px
        if inl_new.sum() < 2:
            break
        inl = inl_new
    out = {}
    pred = _fit_predict(brd[inl], img[inl], brd)
    for t in np.flatnonzero(inl):
        m, (r, c) = cand[t]
        err = 0.0 if pred is None else float(np.hypot(*(pred[t] - img[t])))
        if (r, c) not in out or err < out[(r, c)][0]:
            out[(r, c)] = (err, BoardMatch(int(m.code), r, c, float(m.x_px), float(m.y_px)))
    return [out[key][1] for key in sorted(out)]


def _fit_predict(src, dst, pts):
    """Fit a homography (>= 5 points, not collinear) or affine map src -> dst and map ``pts``."""
    nsrc = len(src)
    if nsrc < 3:
        return None
    A = np.column_stack([src, np.ones(nsrc)])
    if np.linalg.matrix_rank(A) < 3:
        return None
    if nsrc >= 5:
        import cv2

        H, _ = cv2.findHomography(src.astype(np.float64), dst.astype(np.float64), 0)
        if H is not None and np.all(np.isfinite(H)):
            q = np.column_stack([pts, np.ones(len(pts))]) @ H.T
            if np.all(np.abs(q[:, 2]) > 1e-12):
                return q[:, :2] / q[:, 2:3]
    M, *_ = np.linalg.lstsq(A, dst, rcond=None)
    return np.column_stack([pts, np.ones(len(pts))]) @ M
