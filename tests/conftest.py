"""Shared test set-up: one BLAS thread for the numpy work outside kinid.threads (as the command line does), Agg plots."""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")
