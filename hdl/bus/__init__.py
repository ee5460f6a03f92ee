"""Bus stage: the register map declared as data, the AXI4-Lite register file generated from
it, and rowtrack's map."""
