"""A minimal progress line for long work (stderr, only when it is a terminal or forced)."""
from __future__ import annotations

import sys
import time

__all__ = ["Progress"]


class Progress:
    """Report ``done / total`` on one stderr line, at most every ``interval_s``.

    Parameters
    ----------
    total : int or None
        Number of steps, if known.
    label : str
        What is being counted ("frames", "candidates").
    enabled : bool or None
        Force on/off; by default on when stderr is a terminal.
    interval_s : float
        Minimum time between two updates, seconds.
    """

    def __init__(self, total=None, label: str = "", enabled=None, interval_s: float = 0.2, stream=None):
        self.total = total
        self.label = label
        self.stream = sys.stderr if stream is None else stream
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self.interval_s = interval_s
        self.done = 0
        self._t0 = time.perf_counter()
        self._last = 0.0

    def update(self, n: int = 1) -> None:
        self.done += n
        now = time.perf_counter()
        if self.enabled and (now - self._last >= self.interval_s or self.done == self.total):
            self._last = now
            rate = self.done / max(now - self._t0, 1e-9)
            of = f"/{self.total}" if self.total is not None else ""
            self.stream.write(f"\r{self.label} {self.done}{of}  ({rate:.1f}/s)")
            self.stream.flush()

    def close(self) -> None:
        if self.enabled:
            self.stream.write("\n")
            self.stream.flush()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
