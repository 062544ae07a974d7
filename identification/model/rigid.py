"""The rigid transform that best places one set of matched points on another (Kabsch; Umeyama without scale):
the measurement frame's start of the fit, and the misfit by which the data's units are judged."""
from __future__ import annotations

import numpy as np

__all__ = ["rigid_transform"]


def rigid_transform(p_mm, w_mm) -> tuple:
    """The proper rigid transform ``w ≈ R p + t`` of least squares (Kabsch; Umeyama without scale).

    Parameters
    ----------
    p_mm, w_mm : array (N, 3)
        Matched points, mm.

    Returns
    -------
    R : array (3, 3)
        A rotation (determinant +1, never a reflection).
    t_mm : array (3,)
    """
    p, w = np.asarray(p_mm, float), np.asarray(w_mm, float)
    pc, wc = p.mean(axis=0), w.mean(axis=0)
    U, _, Vt = np.linalg.svd((w - wc).T @ (p - pc))
    sign = np.sign(np.linalg.det(U @ Vt)) or 1.0  # a reflection fits better: turn the weakest direction
    R = U @ np.diag([1.0, 1.0, sign]) @ Vt
    return R, wc - R @ pc
