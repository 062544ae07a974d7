"""Progress of long work, one notion for every command: a counter line (stderr, only when it is a
terminal or forced) and the lines a step has to say (:meth:`Progress.say`).

Library functions that run long take ``progress=`` and pass it through :func:`as_progress`, which
accepts a :class:`Progress`, a text stream (every line said goes there, no counter), a callable
``(done, total)``, or None (silent).

A command's steps that can take seconds without a counter (a fit, a check, a report) are each wrapped in
:func:`step`: on a terminal, a step still running after :data:`STEP_SHOWN_S` says what it is doing, and how
long it took when it ends; a quick step, or one whose stderr is a file or a pipe, says nothing.
"""
from __future__ import annotations

import contextlib
import sys
import threading
import time

__all__ = ["Progress", "as_progress", "step", "STEP_SHOWN_S"]

#: A step of a command says what it is doing once it has run this long, seconds (a quicker one says nothing).
STEP_SHOWN_S = 1.0


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

    def say(self, line: str) -> None:
        """Write one line of what a step did (always, to the stream; a counter line in progress is ended)."""
        if self.enabled and self.done:
            self.stream.write("\n")
        self.stream.write(line + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self.enabled:
            self.stream.write("\n")
            self.stream.flush()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class _Callback(Progress):
    """A Progress that calls ``fn(done, total)`` on every update and says nothing."""

    def __init__(self, fn):
        super().__init__(enabled=False)
        self._fn = fn

    def update(self, n: int = 1) -> None:
        self.done += n
        self._fn(self.done, self.total)

    def say(self, line: str) -> None:
        pass


class _Silent(Progress):
    def __init__(self):
        super().__init__(enabled=False)

    def say(self, line: str) -> None:
        pass


def as_progress(progress, total=None) -> Progress:
    """``progress`` as a :class:`Progress`: itself; a stream (lines said go there, no counter line); a
    callable ``(done, total)``; or None (silent). ``total`` is set when given."""
    if isinstance(progress, Progress):
        out = progress
    elif progress is None:
        out = _Silent()
    elif hasattr(progress, "write"):
        out = Progress(enabled=False, stream=progress)
    elif callable(progress):
        out = _Callback(progress)
    else:
        from .errors import DataError

        raise DataError(f"must be a Progress, a text stream, a callable (done, total) or None, got "
                        f"{type(progress).__name__}", parameter="progress")
    if total is not None:
        out.total = total
    return out


@contextlib.contextmanager
def step(label: str, *, stream=None, after_s: float | None = None):
    """A step of a command that may take seconds: on a terminal (``stream``, default stderr), once it has run
    ``after_s`` (default :data:`STEP_SHOWN_S`) its line ``label …`` appears, and ``label: done in 3.2 s`` when it ends (``stopped after`` when an
    error ends it); silent when it ends sooner or the stream is not a terminal (a script's stderr keeps only its
    errors and warnings)."""
    stream = sys.stderr if stream is None else stream
    if not (hasattr(stream, "isatty") and stream.isatty()):
        yield
        return
    start = time.perf_counter()
    after_s = STEP_SHOWN_S if after_s is None else after_s
    said = threading.Event()
    lock = threading.Lock()
    ended = False

    def say():
        with lock:
            if not ended:
                stream.write(f"{label} …\n")
                stream.flush()
                said.set()

    timer = threading.Timer(after_s, say)
    timer.daemon = True
    timer.start()
    how = "stopped after"  # an error or Ctrl-C ended it
    try:
        yield
        how = "done in"
    finally:
        with lock:
            ended = True
        timer.cancel()
        if said.is_set():
            stream.write(f"{label}: {how} {time.perf_counter() - start:.1f} s\n")
            stream.flush()
