"""One BLAS thread around kinid's dense linear algebra.

kinid's matrices are small (a few thousand rows by a few hundred columns at
most). On them a threaded BLAS costs more than it gives, and far more on a
loaded machine: a 200-posture fit took 1.5–6.8 s with default threads against
0.18 s with one thread on the 2-core development machine. The fit and the
diagnosis therefore run their linear algebra inside :func:`single_blas_thread`,
so the Python API is as fast as the command line whatever the user's
environment. A user who sets ``KINID_BLAS_THREADS`` chooses another limit
(a number of threads, or ``none`` to leave the BLAS library as it is).
"""
from __future__ import annotations

import contextlib
import functools
import os
import threading

__all__ = ["single_blas_thread", "blas_single_threaded"]


@contextlib.contextmanager
def single_blas_thread():
    """Limit BLAS to ``KINID_BLAS_THREADS`` threads (default 1) inside the ``with`` block.

    Nested uses are cheap: only the outermost one talks to the BLAS library.
    """
    if getattr(_state, "depth", 0):
        _state.depth += 1
        try:
            yield
        finally:
            _state.depth -= 1
        return
    setting = os.environ.get("KINID_BLAS_THREADS", "1").strip().lower() or "1"
    _state.depth = 1
    try:
        if setting == "none":
            yield
        else:
            with _controller().limit(limits=max(int(setting), 1) if setting.isdigit() else 1, user_api="blas"):
                yield
    finally:
        _state.depth = 0


_state = threading.local()


@functools.lru_cache(maxsize=1)
def _controller():
    """The BLAS libraries loaded in this process, found once (finding them costs about a millisecond)."""
    import numpy  # noqa: F401 - make sure numpy's BLAS is loaded before it is looked for
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()


def blas_single_threaded(function):
    """Decorator: run ``function`` inside :func:`single_blas_thread`."""
    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        with single_blas_thread():
            return function(*args, **kwargs)

    return wrapper
