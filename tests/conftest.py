"""Shared test set-up: one BLAS thread (see identification.cli.limit_blas_threads), Agg plots."""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")
