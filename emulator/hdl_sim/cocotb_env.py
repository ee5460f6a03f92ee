"""What a cocotb test module (running inside the simulator) knows about its design."""

import json
import os
import pickle
from pathlib import Path

__all__ = ["load_params", "load_sidecar"]


def _build_dir():
    return Path(os.environ["ROWTRACK_BUILD_DIR"])


def load_params():
    """The ``params`` object of the component under test (pickled by ``run_cocotb``)."""
    with open(_build_dir() / "params.pkl", "rb") as f:
        return pickle.load(f)


def load_sidecar():
    """The JSON sidecar (latency, ports) written next to the Verilog."""
    name = os.environ["ROWTRACK_TOPLEVEL"]
    return json.loads((_build_dir() / f"{name}.json").read_text())
