"""One pass of the model over the alignments, a chunk at a time: the residuals, and the Jacobian compressed to the
R factor of its QR decomposition.

A least-squares step needs only JᵀJ and Jᵀr, and the identifiability analysis and the covariance only R: with
``J = Q R``, ``‖r + Jδ‖² = ‖r‖² − ‖Qᵀr‖² + ‖Qᵀr + Rδ‖²``. So the (3N × P) Jacobian is never held whole: each chunk
of :data:`CHUNK_ROWS` alignments is evaluated (Pinocchio) and folded into R by a QR of the stacked rows (TSQR), and
memory stays flat in the number of alignments (the residuals, 3N numbers, are kept).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .machine import Machine
from .observations import Observations
from .residuals import Design, residuals

__all__ = ["Pass", "model_pass_qr", "residuals_chunked", "chunks", "CHUNK_ROWS"]

#: Alignments evaluated at a time.
CHUNK_ROWS = 10_000


@dataclass(frozen=True)
class Pass:
    """Residuals and the compressed Jacobian at one parameter vector.

    Attributes
    ----------
    r : array (N, 3)
        Residuals, µm.
    R : array (P, P)
        ``J = Q R`` (J: the (3N × P) Jacobian, µm per parameter unit; Q with orthonormal columns).
    qtr : array (P,)
        ``Qᵀ r``.
    rest : float
        ``‖r‖² − ‖Qᵀr‖²``: the part of the residual no step can reach.
    """

    r: np.ndarray
    R: np.ndarray
    qtr: np.ndarray
    rest: float


def chunks(d: Design, obs: Observations, chunk: int):
    """(design, observations) of consecutive chunks of at most ``chunk`` alignments."""
    n = len(obs)
    for first in range(0, n, chunk):
        rows = np.arange(first, min(first + chunk, n))
        if len(rows) == n:
            yield d, obs
        else:
            yield replace(d, basis=d.basis[rows]), obs.subset(rows)


def residuals_chunked(machine: Machine, d: Design, obs: Observations, theta, *, chunk: int = CHUNK_ROWS) -> np.ndarray:
    """Residuals (N, 3), µm, evaluated a chunk at a time."""
    parts = [residuals(machine, dc, part, theta, jacobian=False) for dc, part in chunks(d, obs, chunk)]
    return np.concatenate(parts) if parts else np.zeros((0, 3))


def model_pass_qr(machine: Machine, d: Design, obs: Observations, theta, *, chunk: int = CHUNK_ROWS) -> Pass:
    """Residuals and the R factor of the Jacobian of ``d``'s parameters at ``theta``, chunk by chunk."""
    P = d.n_params
    parts = []
    top = np.zeros((0, P + 1))
    for dc, part in chunks(d, obs, chunk):
        r, J, _ = residuals(machine, dc, part, theta)
        parts.append(r)
        stacked = np.vstack([top, np.column_stack([J.reshape(-1, P), r.ravel()])])
        top = np.linalg.qr(stacked, mode="r")[: P + 1]
    if top.shape[0] < P + 1:
        top = np.vstack([top, np.zeros((P + 1 - top.shape[0], P + 1))])
    return Pass(np.concatenate(parts) if parts else np.zeros((0, 3)), top[:P, :P], top[:P, P], float(top[P, P] ** 2))
