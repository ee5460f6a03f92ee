"""The rolling-shutter camera-cluster simulator: rig + scene + trajectory → dataset.

Each row of each camera is rendered at its own time ``τ0 + jitter_i + y·t_r + i/fps`` from
the rig pose at that time (optionally averaged over the exposure for motion blur), then
goes through the sensor: additive Gaussian noise and 8-bit quantization. The row times
and the exact rig poses and velocities at those times are the ground truth.
"""

import cv2
import numpy as np

from .dataset import CameraRecording, Dataset
from .render import Renderer
from .scene import build_scene

__all__ = ["MIN_CLEARANCE", "schedule", "check_clearance", "sensor", "render_frames", "simulate"]

#: Smallest allowed distance (m) from any camera centre to a surface.
MIN_CLEARANCE = 0.1


def schedule(rig, duration, seed):
    """Row times (F, H) of every camera for frames started in ``[0, duration)``; the
    per-frame trigger jitter comes from ``seed``."""
    if not duration > 0:
        raise ValueError(f"duration must be positive, not {duration!r}")
    times = []
    for k, cam in enumerate(rig.cameras):
        frames = cam.frame_count(duration)
        if frames == 0:
            raise ValueError(f"duration {duration} s ends before camera {cam.name!r} starts "
                             f"its first frame (trigger_offset {cam.trigger_offset} s)")
        rng = np.random.default_rng([seed, 1, k])
        jitter = rng.normal(0.0, cam.trigger_jitter, frames) if cam.trigger_jitter else 0.0
        times.append(cam.row_times(np.arange(frames), jitter))
    return times


def check_clearance(rig, scene_spec, trajectory, times):
    """Raise ValueError if a camera centre comes closer than MIN_CLEARANCE to a surface."""
    for cam, cam_times in zip(rig.cameras, times):
        t = cam_times.ravel()
        rotation, position = trajectory.pose(t)
        centres = rotation @ cam.c + position
        clearance = scene_spec.clearance(centres)
        worst = int(np.argmin(clearance))
        if clearance[worst] < MIN_CLEARANCE:
            raise ValueError(
                f"camera {cam.name!r} comes within {clearance[worst]:.3f} m of a surface "
                f"(or leaves the room) at t = {t[worst]:.4f} s, at {np.round(centres[worst], 3)}; "
                f"shorten the duration or change the motion")


def sensor(radiance, noise_sigma, seed):
    """8-bit readout of a radiance image: additive Gaussian noise (std ``noise_sigma``
    gray levels, from ``seed``), rounding and clipping to [0, 255]."""
    image = radiance
    if noise_sigma > 0:
        noise = np.empty_like(radiance)
        cv2.setRNGSeed(int(seed))
        cv2.randn(noise, 0.0, float(noise_sigma))
        image = radiance + noise
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def _exposure_times(cam, row_times):
    """Times at which a row is rendered: the row time, or N exposure midpoints."""
    if cam.exposure_samples == 1:
        return [row_times]
    n = cam.exposure_samples
    return [row_times + (s + 0.5) / n * cam.t_e for s in range(n)]


def render_frames(rig, scene, trajectory, times, seed):
    """Yield ``(camera index, frame index, uint8 rows (H, W))`` for every frame, camera by
    camera, frame by frame."""
    for k, (cam, cam_times) in enumerate(zip(rig.cameras, times)):
        renderer = Renderer(scene, cam)
        for i, row_times in enumerate(cam_times):
            radiance = None
            for t in _exposure_times(cam, row_times):
                rotation, position = trajectory.pose(t)
                image = renderer.render(rotation @ cam.R, rotation @ cam.c + position)
                radiance = image if radiance is None else radiance + image
            radiance /= np.float32(cam.exposure_samples)
            noise_seed = np.random.SeedSequence([seed, 2, k, i]).generate_state(1)[0] >> 1
            yield k, i, sensor(radiance, cam.noise_sigma, noise_seed)


def simulate(rig, scene_spec, trajectory, duration, *, seed=0, progress=False):
    """Simulate ``duration`` seconds; returns a :class:`golden.dataset.Dataset`.

    Raises
    ------
    ValueError
        For a non-positive duration, or a trajectory that takes a camera into a wall.
    """
    times = schedule(rig, duration, seed)
    check_clearance(rig, scene_spec, trajectory, times)
    scene = build_scene(scene_spec)
    recordings = []
    for cam, cam_times in zip(rig.cameras, times):
        rotation, position = trajectory.pose(cam_times.ravel())
        velocity, angular = trajectory.velocity(cam_times.ravel())
        shape = cam_times.shape
        recordings.append(CameraRecording(
            rows=np.empty(shape + (cam.width,), np.uint8), time=cam_times,
            rotation=rotation.reshape(shape + (3, 3)), position=position.reshape(shape + (3,)),
            velocity=velocity.reshape(shape + (3,)), angular_velocity=angular.reshape(shape + (3,))))
    frames = render_frames(rig, scene, trajectory, times, seed)
    if progress:
        from tqdm import tqdm
        frames = tqdm(frames, total=sum(len(t) for t in times), unit="frame",
                      desc=f"simulate {rig.name}")
    for k, i, rows in frames:
        recordings[k].rows[i] = rows
    info = {"seed": seed, "duration": duration, "scene": scene_spec.to_dict(),
            "trajectory": trajectory.to_dict(), "observability": rig.observability.to_dict()}
    return Dataset(rig=rig, cameras=recordings, info=info)
