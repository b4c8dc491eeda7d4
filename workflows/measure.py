"""Measurement helpers at the edges: peak memory of a block of code."""
from __future__ import annotations

import threading
from contextlib import contextmanager


@contextmanager
def peak_rss(interval: float = 0.005):
    """Sample the process's resident memory in a thread; yields a dict whose
    ``peak_mb`` is the peak increase over the start (MB) once the block exits.
    Sampling can miss spikes shorter than ``interval``."""
    import psutil

    proc = psutil.Process()
    base = proc.memory_info().rss
    out = {"peak_mb": 0.0}
    stop = threading.Event()

    def sample():
        peak = base
        while not stop.is_set():
            peak = max(peak, proc.memory_info().rss)
            stop.wait(interval)
        out["peak_mb"] = (max(peak, proc.memory_info().rss) - base) / 2 ** 20

    thread = threading.Thread(target=sample, daemon=True)
    thread.start()
    try:
        yield out
    finally:
        stop.set()
        thread.join()
