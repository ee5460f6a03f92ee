"""Measurement stage: the engine (row-set fork, one temporal lane per camera, one stereo
lane per pair) and the router that turns segment measurements into the solver's slots."""
