"""Bit-accurate models of the front end (:mod:`hdl.front_end`)."""
