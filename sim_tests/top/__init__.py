"""Tests of the top, the board tops, the pipeline, ``rowtrack run`` and the co-simulated
slice; cocotb bench in ``rowtrack_top/``."""
