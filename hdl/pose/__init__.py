"""Pose stage: the parts of :mod:`hdl.pose_solver` (parameters, the scheduled row program,
the accumulator of the normal equations, the engine that runs the program, the MAC)."""
