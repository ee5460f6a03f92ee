"""Row slots: the tracker's clock.

Every camera of a rig reads one row per row period ``t_r``. The tracker solves one
system per *slot* — one tick of that clock — from the rows of all cameras read in it
(each row joins the slot nearest its recorded time). With synchronized triggers a slot
holds row y of every camera; with trigger offsets a slot holds different row indices
of different cameras (more independent equations, TVCG 2016 §4), and a camera in its
blanking interval simply contributes nothing to that slot (the row updates with fewer
equations, subject to the conditioning gate).

All cameras must share the image size, frame rate and row period.
"""

import numpy as np

__all__ = ["RowSlots"]


class RowSlots:
    """The slot of every camera row of a dataset.

    Members
    -------
    times : (S,) float
        Time of each slot (s).
    period : float
        Frame period 1/fps.
    first_tracked : int
        First slot after every camera has read its whole first frame; earlier slots are
        the initialisation (their poses are given).
    """

    def __init__(self, dataset):
        cams = dataset.rig.cameras
        for name in ("width", "height", "fps", "t_r"):
            values = {getattr(c, name) for c in cams}
            if len(values) > 1:
                raise ValueError(f"the tracker needs cameras with one {name}; rig "
                                 f"{dataset.rig.name!r} has {sorted(values)}")
        self.t_r, self.period = cams[0].t_r, 1.0 / cams[0].fps
        start = min(rec.time[0, 0] for rec in dataset.cameras)
        self._slot = [np.rint((rec.time - start) / self.t_r).astype(np.int64)
                      for rec in dataset.cameras]
        for k, slots in enumerate(self._slot):
            flat = slots.ravel()
            if np.any(np.diff(flat) <= 0):
                raise ValueError(f"camera {cams[k].name!r} reads two rows within one row "
                                 f"period (trigger jitter above t_r/2?)")
        count = max(int(s.max()) for s in self._slot) + 1
        self.times = start + np.arange(count) * self.t_r
        occupied = np.zeros(count, dtype=bool)
        for slots in self._slot:
            occupied[slots.ravel()] = True
        self.occupied = occupied
        if any(rec.time.shape[0] < 2 for rec in dataset.cameras):
            raise ValueError("the tracker needs at least two frames from every camera")
        self.first_tracked = max(int(s[1, 0]) for s in self._slot)

    def __len__(self):
        return len(self.times)

    def members(self, camera, first, stop):
        """Frames, rows and slots of ``camera``'s rows read in slots ``[first, stop)``."""
        slots = self._slot[camera]
        flat = slots.ravel()
        lo, hi = np.searchsorted(flat, first), np.searchsorted(flat, stop)
        index = np.arange(lo, hi)
        frames, rows = np.divmod(index, slots.shape[1])
        return frames, rows, flat[lo:hi]
