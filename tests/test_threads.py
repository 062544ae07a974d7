"""kinid limits BLAS threads itself around its dense linear algebra."""
import numpy as np
from threadpoolctl import threadpool_info

from kinid.threads import blas_single_threaded, single_blas_thread


def _blas_threads():
    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]


def test_one_blas_thread_inside_and_restored_after(monkeypatch):
    monkeypatch.delenv("KINID_BLAS_THREADS", raising=False)
    np.linalg.qr(np.ones((3, 3)))  # BLAS loaded
    before = _blas_threads()
    with single_blas_thread():
        assert set(_blas_threads()) == {1}
        with single_blas_thread():  # nested: still one, and leaving it keeps the outer limit
            assert set(_blas_threads()) == {1}
        assert set(_blas_threads()) == {1}
    assert _blas_threads() == before


def test_decorated_functions_run_single_threaded(monkeypatch):
    monkeypatch.delenv("KINID_BLAS_THREADS", raising=False)
    seen = blas_single_threaded(_blas_threads)()
    assert set(seen) == {1}


def test_the_user_can_choose_the_limit(monkeypatch):
    monkeypatch.setenv("KINID_BLAS_THREADS", "none")
    before = _blas_threads()
    with single_blas_thread():
        assert _blas_threads() == before
