"""Row-descriptor stage: the parts of the lanes in :mod:`hdl.row_descriptor` (parameters,
stream layouts, the previous frame's row store, the matcher)."""
