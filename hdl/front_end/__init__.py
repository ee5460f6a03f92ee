"""Front end: the cameras' DVP inputs in their pixel-clock domains, the trigger and sync
monitor, and the row aligner that hands the engine one row set at a time."""
