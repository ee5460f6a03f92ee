"""The PNG plots of ``build/report/`` (:mod:`emulator.report`).

The golden tracker's trajectory against ground truth is the ``rowtrack track`` plot
(:func:`emulator.commands.track.plot_trajectory`); this module adds the per-axis plots
of the hardware path against golden (b) and truth (trajectory, per-row one-frame motion,
its error) and the per-camera confidence.
"""

import numpy as np

from golden.pose_lsq import UNKNOWNS

__all__ = ["plot_axes", "plot_confidence", "emulator_camera_confidence"]

#: Scale and unit per axis: translations in cm, rotations in degrees.
_UNITS = [(100.0, "cm")] * 3 + [(180 / np.pi, "deg")] * 3


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def plot_axes(path, ms, series, title, extra=None):
    """One panel per axis ``[T θ]`` of the (n, 6) arrays ``series`` (label → array)
    against ``ms`` (time of each row, ms), and of ``extra`` (label → (ms, array)) rows
    of their own times; NaN rows are gaps."""
    plt = _pyplot()
    fig, axes = plt.subplots(2, 3, figsize=(14, 7), sharex=True)
    every = [(label, ms, values) for label, values in series.items()] + \
        [(label, *times_values) for label, times_values in (extra or {}).items()]
    for k, (ax, name) in enumerate(zip(axes.ravel(), UNKNOWNS)):
        scale, unit = _UNITS[k]
        for label, times, values in every:
            ax.plot(times, scale * values[:, k], ".", ms=2, label=label)
        ax.set_title(f"{name} ({unit})", fontsize=9)
        ax.grid(alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("time since the first row, ms")
    axes[0, 0].legend(fontsize=8, markerscale=4)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def emulator_camera_confidence(config, result):
    """Largest routed confidence of each camera in each record, (n, cameras)."""
    solver, rows = config.router.solver, result.rows
    conf = np.zeros((len(rows), solver.slots))
    index = np.arange(len(rows))[:, None]
    conf[index, rows.slot] = np.where(rows.present, solver.conf_fmt.to_float(rows.conf), 0)
    return conf.reshape(len(rows), config.router.cameras, -1).max(axis=-1)


def plot_confidence(path, golden_ms, golden_conf, emulator_ms, emulator_conf,
                    golden_label="golden tracker"):
    """Per-camera confidence over time: the golden tracker's (``golden_label``) best
    segment confidence and the emulator's largest routed confidence (the solver's
    weight)."""
    plt = _pyplot()
    fig, axes = plt.subplots(2, 1, figsize=(13, 7), sharex=True)
    for ax, ms, conf, title in ((axes[0], golden_ms, golden_conf, f"{golden_label}: best "
                                 "segment confidence"),
                                (axes[1], emulator_ms, emulator_conf, "emulator: largest "
                                 "routed confidence (solver weight)")):
        image = ax.imshow(np.nan_to_num(conf).T, aspect="auto", origin="lower",
                          interpolation="nearest", cmap="viridis",
                          extent=(ms[0], ms[-1], -0.5, conf.shape[1] - 0.5))
        ax.set_ylabel("camera")
        ax.set_title(title, fontsize=9)
        fig.colorbar(image, ax=ax)
    axes[1].set_xlabel("time since the first row, ms")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
