"""The sums over alignments the score test (:mod:`~kinid.identification.diagnosis.scoring`) needs: candidates grouped by
error joint, their basis values computed once per fit for every joint of an axis, each joint's series, the sums of a
group over chunks of alignments, and the explicitly projected columns of nearly aliased candidates.

A candidate's whitened column is its error joint's column times its basis values, so every sum the test needs is a
sum over the N alignments of basis values times a few series of the joint (not over the 3N coordinates of each
column); memory stays flat in N (chunks of alignments, a budget for what is kept).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model import basis_of

__all__ = ["Memo", "MEMO_BYTES", "Columns", "column_groups", "basis_values_once", "joint_series", "group_sums",
           "projected_exactly", "model_products", "SCORE_BLOCK_BYTES", "EXACT_ROWS", "EXACT_COLUMNS"]

#: Memory for the basis values of one group of candidates over a chunk of alignments in the score test, bytes
#: (diagnosis memory stays flat in N).
SCORE_BLOCK_BYTES = 64 * 1024 * 1024


#: Memory a fit side keeps for what many score tests read (basis values shared by the joints of an axis, each
#: joint's series), bytes; beyond it they are computed each time they are needed (memory flat in N).
MEMO_BYTES = 64 * 1024 * 1024


class Memo:
    """Arrays (or tuples of arrays) computed once per fit side, by key, up to MEMO_BYTES in all; ``always``: kept
    whatever the budget (what is small and read for every other value: an axis's positions)."""

    def __init__(self):
        self.values, self.bytes = {}, 0

    def get(self, key, make, always: bool = False):
        out = self.values.get(key)
        if out is None:
            out = make()
            size = sum(a.nbytes for a in (out if isinstance(out, tuple) else (out,)))
            if always or self.bytes + size <= MEMO_BYTES:
                self.values[key], self.bytes = out, self.bytes + size
        return out


@dataclass(frozen=True)
class Columns:
    """The basis values of candidates of one error joint, summed together.

    Attributes
    ----------
    joint : int
        The error joint (index in ``machine.error_joints``).
    members : list of (int, Effect, array of int)
        Each candidate's position in the list scored, the effect, and its columns among the group's.
    width : int
        Columns of the group.
    values : callable (slice of rows) -> array (rows, width)
        The group's basis values at those alignments.
    shared : bool
        The members share columns (windows of one knot grid): their Gram matrices are sub-blocks of the group's.
        Otherwise each member's columns are its own, and only its block of the Gram matrix is summed.
    key : tuple
        The members' axes and names after their joint's code: groups of the same key (joints of one axis with the
        same candidates) have the same basis values.
    """

    joint: int
    members: list
    width: int
    values: object
    shared: bool
    key: tuple = ()


def column_groups(machine, obs, candidates, memo: Memo) -> list:
    """``candidates`` in groups of one error joint (:class:`Columns`), joint by joint: local errors by knot grid
    (each window's columns a subset of the grid's B-splines, computed once), every other candidate with the
    other candidates of its joint (each basis's values over a chunk of alignments computed once in ``memo``, for
    all the joints of its axis)."""
    from ..model import local_column_index, local_columns

    codes = machine.error_codes
    n = len(obs)
    plain, grids = {}, {}
    for i, e in enumerate(candidates):
        if basis_of(e).joints is not None:  # spread over several joints: scored from its own columns
            continue
        j = codes.index(e.code)
        grid = basis_of(e).window_grid
        if grid is not None:
            grids.setdefault((j, e.axis, grid(e)), []).append((i, e))
        else:
            plain.setdefault(j, []).append((i, e))

    def basis(e, c):
        return basis_values_once(machine, obs, e, c, memo)

    def shape(effects) -> tuple:  # the same for every joint of an axis with the same candidates
        return tuple((e.axis, e.name.partition(":")[2]) for e in effects)

    groups = []
    for j, members in plain.items():
        effects = [e for _, e in members]
        edges = np.cumsum([0] + [e.n_params for e in effects])
        groups.append(Columns(j, [(i, e, np.arange(a, b)) for (i, e), a, b in zip(members, edges[:-1], edges[1:])],
                              int(edges[-1]), lambda c, effects=effects, key=shape(effects): memo.get(
                                  ("columns", key, c.start, c.stop),
                                  lambda: np.concatenate([basis(e, c) for e in effects], axis=1)), False,
                              shape(effects)))
    for (j, axis, grid), members in grids.items():
        effects = [e for _, e in members]
        q = obs.axes[:, machine.axis_names.index(axis)]
        key = shape(effects)
        index = memo.get(("local index", key), lambda: tuple(local_column_index(effects, q)))
        groups.append(Columns(j, [(i, e, ix) for (i, e), ix in zip(members, index)],
                              local_columns(effects, q, slice(0, 0)).shape[1],
                              lambda c, effects=effects, q=q, key=key: memo.get(
                                  ("local", key, c.start, c.stop), lambda: local_columns(effects, q, c)), True, key))
    groups.sort(key=lambda g: g.joint)  # stable: in the candidates' order within a joint
    return groups


def basis_values_once(machine, obs, e, c: slice, memo: Memo) -> np.ndarray:
    """The basis values of candidate ``e`` at the alignments ``c`` of ``obs``, computed once in ``memo`` by the
    basis's name after the joint's code and its axis (the same for every joint of the axis); a basis driven by an
    axis read at a few positions (a table's angles) evaluated once per position."""
    from ..model import basis_values

    def make():  # the rows' readings as views (no Observations.subset: it copies every column, marks included)
        if basis_of(e).driver == "position":
            k = machine.axis_names.index(e.axis)
            at, back = memo.get(("positions", k), lambda: np.unique(obs.axes[:, k], return_inverse=True), always=True)
            if 4 * at.size <= len(obs):
                axes = np.zeros((at.size, obs.axes.shape[1]))
                axes[:, k] = at
                return basis_values(e, machine, axes)[back[c]]
        return basis_values(e, machine, obs.axes[c], t_s=None if obs.t_s is None else np.asarray(obs.t_s)[c],
                            directions={a: np.asarray(d)[c] for a, d in (obs.directions or {}).items()})
    return memo.get(("basis", e.axis, e.name.partition(":")[2], c.start, c.stop), make)


def joint_series(col, Q0, r, q0r) -> tuple:
    """Series over the N alignments of one error joint whose whitened column is ``col`` (N, 3): its squared norm,
    its product with the residual and with the model's orthonormal basis (N, rank); and Q0ᵀ r (``q0r``)."""
    n = col.shape[0]
    nrm = np.einsum("nk,nk->n", col, col)
    rw = np.einsum("nk,nk->n", col, r.reshape(n, 3))
    g = np.einsum("nkr,nk->nr", Q0.reshape(n, 3, -1), col)
    return nrm, rw, g, q0r


def group_sums(group: Columns, series, n: int, memo: Memo | None = None) -> tuple:
    """For the columns of ``group``: squared norms (width,), products with the model's orthonormal basis
    (rank, width), the projected columns' product with the residual (width,), and the members' Gram matrices
    projected off the model, CᵀC − AᵀA, by their number of columns k: {k: (the members' places in
    ``group.members``, their matrices (members, k, k))}; summed over chunks of alignments whose basis values fit
    SCORE_BLOCK_BYTES.

    Members of their own columns have their Gram blocks from one product of the joint's series with the products of
    their pairs of basis columns (the same for every joint of an axis with the same candidates: kept in ``memo``);
    members that share columns (windows of one grid), from sub-blocks of the group's Gram matrix, projected once."""
    nrm, rw, g, s0 = series
    width = group.width
    # members by their number of columns: their blocks gathered and projected at once
    sizes = {}
    for m, (_, _, ix) in enumerate(group.members):
        sizes.setdefault(ix.size, []).append(m)
    index = {k: np.array([group.members[m][2] for m in ms]).reshape(len(ms), k) for k, ms in sizes.items()}
    if group.shared:
        pairs = 0
    else:  # each member's pairs of columns (i, j), member after member
        left = np.concatenate([np.repeat(ix, ix.size) for _, _, ix in group.members])
        right = np.concatenate([np.tile(ix, ix.size) for _, _, ix in group.members])
        pairs = left.size
    rows = max(64, int(SCORE_BLOCK_BYTES // (8 * 4 * max(width + pairs, 1))))
    norm2, A, rwB = np.zeros(width), np.zeros((g.shape[1], width)), np.zeros(width)
    gram = np.zeros((width, width)) if group.shared else np.zeros(pairs)
    for a in range(0, n, rows):
        c = slice(a, min(a + rows, n))
        B = group.values(c)
        A += g[c].T @ B
        rwB += rw[c] @ B
        if group.shared:
            norm2 += nrm[c] @ (B * B)
            gram += (B * nrm[c, None]).T @ B
        else:
            def products(B=B):
                return B[:, left] * B[:, right]
            P = products() if memo is None else memo.get(("pairs", group.key, c.start, c.stop), products)
            gram += nrm[c] @ P
    bvec = rwB - A.T @ s0  # (C − Q0 A)ᵀ r, with Q0ᵀ r ≈ 0
    if group.shared:
        gram -= A.T @ A  # projected off the model once: each window's block is a sub-block
        return norm2, A, bvec, {k: (ms, gram[index[k][:, :, None], index[k][:, None, :]]) for k, ms in sizes.items()}
    on_diagonal = left == right
    norm2[left[on_diagonal]] = gram[on_diagonal]
    edges = np.cumsum([0] + [ix.size**2 for _, _, ix in group.members])
    blocks = {}
    for k, ms in sizes.items():
        Ak = A[:, index[k]]  # (rank, members, k)
        own = np.array([gram[edges[m]:edges[m + 1]] for m in ms]).reshape(len(ms), k, k)
        blocks[k] = (ms, own - np.einsum("rmi,rmj->mij", Ak, Ak))
    return norm2, A, bvec, blocks


#: Alignments per chunk of the explicitly projected columns (memory flat in N), and columns projected at once (a
#: chunk of them is 3 × EXACT_ROWS × EXACT_COLUMNS numbers, 12.6 MB).
EXACT_ROWS = 8192
EXACT_COLUMNS = 64


def projected_exactly(col, basis, k, Q0, r) -> tuple:
    """For candidates of ``k`` columns each, ``col`` × ``basis`` of one joint (col (N, 3), basis (N, m·k), a
    candidate's basis values side by side): their Gram matrices projected off the model (m, k, k) and the projected
    columns' products with r (m, k), from the projected columns, in chunks of alignments."""
    n, width = basis.shape
    m = width // k
    chunks = [slice(a, min(a + EXACT_ROWS, n)) for a in range(0, n, EXACT_ROWS)]

    def columns(c):
        return (col[c, :, None] * basis[c, None, :]).reshape(-1, width)

    def rows(c):
        return slice(3 * c.start, 3 * c.stop)

    kept = columns(chunks[0]) if len(chunks) == 1 else None  # one chunk: its columns serve both passes
    A = sum(Q0[rows(c)].T @ (columns(c) if kept is None else kept) for c in chunks)
    grams, bvec = np.zeros((m, k, k)), np.zeros(width)
    for c in chunks:
        Cp = (columns(c) if kept is None else kept) - Q0[rows(c)] @ A
        bvec += Cp.T @ r[rows(c)]
        Cp = Cp.reshape(-1, m, k).transpose(1, 0, 2)  # (m, rows, k): one matrix product per candidate
        grams += np.matmul(Cp.transpose(0, 2, 1), Cp)
    return grams, bvec.reshape(m, k)


def model_products(col, basis, J0) -> np.ndarray:
    """The product (p0, k) of the model's columns ``J0`` with the columns ``col`` × ``basis`` of one joint."""
    n, k = basis.shape
    return sum(J0[3 * a:3 * min(a + EXACT_ROWS, n)].T
               @ (col[a:a + EXACT_ROWS, :, None] * basis[a:a + EXACT_ROWS, None, :]).reshape(-1, k)
               for a in range(0, n, EXACT_ROWS))
