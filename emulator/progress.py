"""Progress of long phases whose work cannot be counted from outside (elaborating a
design to Verilog, a cocotb simulation in its own process): a bar over seconds whose
total is the time the same phase took the last time, kept in a small JSON file under
``build/``. The first time the caller may give an estimate measured elsewhere; without one the bar
shows the elapsed time.
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
def timed_phase(desc, key, record, enabled=True, fallback=None):
    """Show a bar for the block, described ``desc``, estimated from ``record`` (a JSON
    file of ``{key: seconds}``), or from ``fallback`` seconds when the record has none
    (a figure measured elsewhere, such as a benchmark's); the block's wall time is
    written back under ``key`` when it finishes without an exception. Yields nothing;
    with ``enabled`` false only the time is recorded."""
    from tqdm import tqdm
    estimate = _load(record).get(key, fallback)
    done = threading.Event()
    start = time.perf_counter()

    def left():
        remaining = estimate - (time.perf_counter() - start)
        return (f"about {tqdm.format_interval(remaining)} left" if remaining > 0
                else "longer than estimated")

    def show():
        if estimate is None:
            label, bar_format = f"{desc} (no estimate yet)", "{desc}: {elapsed} elapsed"
        else:
            label, bar_format = desc, "{desc}: {elapsed} elapsed{postfix}"
        with tqdm(desc=label, leave=False, bar_format=bar_format,
                  postfix=None if estimate is None else left()) as bar:
            while not done.wait(0.5):
                if estimate is not None:
                    bar.set_postfix_str(left(), refresh=False)
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
