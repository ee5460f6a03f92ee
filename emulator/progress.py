"""Progress of long phases whose work cannot be counted from outside (elaborating a
design to Verilog, a cocotb simulation in its own process): a bar over seconds whose
total is the time the same phase took the last time, kept in a small JSON file under
``build/``. The first time there is no estimate and the bar shows the elapsed time.
"""

import json
import threading
import time
from contextlib import contextmanager
from pathlib import Path

__all__ = ["timed_phase"]


def _load(path):
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return {}


@contextmanager
def timed_phase(desc, key, record, enabled=True):
    """Show a bar for the block, described ``desc``, estimated from ``record`` (a JSON
    file of ``{key: seconds}``); the block's wall time is written back under ``key``
    when it finishes without an exception. Yields nothing; with ``enabled`` false only
    the time is recorded."""
    from tqdm import tqdm
    estimate = _load(record).get(key)
    done = threading.Event()
    start = time.perf_counter()

    def show():
        total = round(estimate, 1) if estimate else None
        label = desc + ("" if total else " (no estimate yet)")
        with tqdm(desc=label, total=total, unit="s", leave=False,
                  bar_format="{desc}: {elapsed} elapsed, about {remaining} left"
                  if total else "{desc}: {elapsed} elapsed") as bar:
            while not done.wait(0.5):
                bar.n = min(round(time.perf_counter() - start, 1), total or float("inf"))
                bar.refresh()

    thread = threading.Thread(target=show, daemon=True) if enabled else None
    if thread:
        thread.start()
    try:
        yield
    finally:
        done.set()
        if thread:
            thread.join()
    times = _load(record)
    times[key] = time.perf_counter() - start
    Path(record).parent.mkdir(parents=True, exist_ok=True)
    Path(record).write_text(json.dumps(times, indent=1, sort_keys=True))
