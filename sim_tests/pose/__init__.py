"""Tests of the pose solver, its model and the golden least squares; cocotb benches in
``pose_solver/`` and ``mac/``."""
