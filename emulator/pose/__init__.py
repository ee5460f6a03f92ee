"""Bit-accurate models of the pose stage's parts (:mod:`hdl.pose`); the solver's model is
:mod:`emulator.pose_solver`."""
