"""One Levenberg–Marquardt step of the fit, with box bounds: a small dense QP solved by CasADi (qrqp).

The step's data go to CasADi as one NumPy vector (the scaled Jacobian's columns, the residual, the bounds, λ),
unpacked and turned into the QP inside a CasADi function made once per size: converting each array to a
``casadi.DM`` on its own cost more than the solve (about 0.1 ms of a 0.15 ms step). The vector is written into
the function's input buffer, and the step read from its output buffer: no conversion at all.
"""
from __future__ import annotations

import functools
import threading

import casadi as ca
import numpy as np

__all__ = ["lm_step", "below_noise", "STOP_STEP_STD"]

#: The iterations end where the Gauss–Newton step left moves the parameters by less than this share of their
#: standard deviation (its length in the metric of their covariance): the data cannot tell the step from zero.
STOP_STEP_STD = 1e-3


@functools.lru_cache(maxsize=32)
def _step_function(m: int, n: int):
    """CasADi function: packed [Js (m × n, column-major), r (m), lbx (n), ubx (n), λ] -> δ of one step."""
    opts = {"print_iter": False, "print_header": False, "print_info": False, "error_on_fail": False}
    qp = ca.conic("lm_step", "qrqp", {"h": ca.Sparsity.dense(n, n), "a": ca.Sparsity(0, n)}, opts)
    v = ca.MX.sym("v", m * n + m + 2 * n + 1)
    Js, r = ca.reshape(v[: m * n], m, n), v[m * n : m * n + m]
    lbx, ubx, lam = v[m * n + m : m * n + m + n], v[m * n + m + n : m * n + m + 2 * n], v[-1]
    H = ca.mtimes(Js.T, Js) + lam * ca.MX.eye(n)
    x = qp(h=H, g=ca.mtimes(Js.T, r), lbx=lbx, ubx=ubx, a=ca.MX(0, n), lba=ca.MX(0, 1), uba=ca.MX(0, 1))["x"]
    return ca.Function("lm_step", [v], [x])


def _step_buffers(m: int, n: int):
    """The step function of this size called through CasADi's buffers (its input and output NumPy arrays it reads
    and writes in place: a call with a NumPy argument spends 45 µs converting 600 numbers to a ``DM``, three times
    the solve), one set per thread."""
    key = (m, n, threading.get_ident())
    if key not in _BUFFERS:
        if len(_BUFFERS) >= 64:  # sizes of models past, threads ended
            _BUFFERS.clear()
        buffer, call = _step_function(m, n).buffer()
        packed, delta = np.zeros(m * n + m + 2 * n + 1), np.zeros(n)
        buffer.set_arg(0, memoryview(packed))
        buffer.set_res(0, memoryview(delta))
        _BUFFERS[key] = (buffer, call, packed, delta)  # the buffer kept alive with the arrays it points into
    return _BUFFERS[key]


_BUFFERS: dict = {}


def lm_step(Js, r, lam, lbx, ubx):
    """δ minimising ½‖Js δ + r‖² + ½ λ‖δ‖² within [lbx, ubx] (scaled units)."""
    m, n = Js.shape
    _, call, packed, delta = _step_buffers(m, n)
    np.concatenate([np.ravel(Js, order="F"), r, lbx, ubx, [lam]], out=packed)
    call()
    return delta.copy()


def below_noise(predicted: float, cost: float, noise_um: float | None, dof: int) -> bool:
    """Whether a Gauss–Newton step whose predicted decrease of the cost ½‖r‖² (µm²) is ``predicted`` is one the data
    cannot tell from zero: ``predicted`` = ½‖J δ‖², so ‖J δ‖ / σ, the step's length in the metric of the
    parameters' covariance, is below :data:`STOP_STEP_STD`. σ is ``noise_um``, or the residuals' (from ``cost``
    over ``dof`` degrees of freedom) where it is None."""
    sigma2 = noise_um**2 if noise_um else (2 * cost / dof if dof > 0 else 0.0)
    return sigma2 > 0 and predicted <= 0.5 * STOP_STEP_STD**2 * sigma2
