"""One Levenberg–Marquardt step of the fit, with box bounds: a small dense QP solved by CasADi (qrqp).

The QP's arrays go to CasADi as NumPy arrays, converted once inside the call: wrapping each in a ``casadi.DM``
first cost as much as the solve (about 0.1 ms of a 0.2 ms step).
"""
from __future__ import annotations

import functools

import casadi as ca
import numpy as np

__all__ = ["lm_step"]


@functools.lru_cache(maxsize=32)
def _step_solver(n: int):
    """CasADi QP for one Levenberg–Marquardt step in ``n`` scaled parameters."""
    opts = {"print_iter": False, "print_header": False, "print_info": False, "error_on_fail": False}
    return ca.conic("lm_step", "qrqp", {"h": ca.Sparsity.dense(n, n), "a": ca.Sparsity(0, n)}, opts)


def lm_step(Js, r, lam, lbx, ubx):
    """δ minimising ½‖Js δ + r‖² + ½ λ‖δ‖² within [lbx, ubx] (scaled units)."""
    n = Js.shape[1]
    H = Js.T @ Js + lam * np.eye(n)
    g = Js.T @ r
    none, empty = _no_constraints(n)
    sol = _step_solver(n)(h=H, g=g, lbx=lbx, ubx=ubx, a=none, lba=empty, uba=empty)
    return np.asarray(sol["x"]).ravel()


@functools.lru_cache(maxsize=32)
def _no_constraints(n: int) -> tuple:
    """The QP's empty constraint matrix (0 × n) and bounds, made once per size."""
    return ca.DM(0, n), ca.DM(0, 1)
