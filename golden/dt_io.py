"""Image files for the domain-transform tools: 8- or 16-bit in, the same depth out.

OpenCV reads and writes the files. Values keep their integer scale (a 16-bit depth map
stays in its own units); :func:`unit_scale` maps an image to [0, 1] by its bit depth
(what guides and confidences need).
"""

from pathlib import Path

import cv2
import numpy as np

__all__ = ["read_image", "unit_scale", "write_like", "check_writable"]

_DEPTHS = {np.dtype(np.uint8): 255.0, np.dtype(np.uint16): 65535.0}


def read_image(path, what):
    """An 8- or 16-bit image file as an integer array (H, W) or (H, W, C).

    Raises
    ------
    ValueError
        If the file is missing, unreadable, or not 8/16-bit; the message names ``what``.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{what} {str(path)!r} does not exist")
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise ValueError(f"{what} {str(path)!r} is not an image OpenCV can read")
    if image.dtype not in _DEPTHS:
        raise ValueError(f"{what} {str(path)!r} must be 8- or 16-bit, not {image.dtype}")
    if image.ndim == 3 and image.shape[2] == 4:
        image = image[..., :3]  # alpha is not an edge
    return image


def unit_scale(image):
    """An 8- or 16-bit image as float64 in [0, 1]."""
    return np.asarray(image, dtype=np.float64) / _DEPTHS[np.asarray(image).dtype]


def check_writable(path, what):
    """Fail early (ValueError) if ``path`` cannot be written as an image."""
    path = Path(path)
    if not path.parent.is_dir():
        raise ValueError(f"{what} directory {str(path.parent)!r} does not exist")
    if not cv2.haveImageWriter(str(path)):
        raise ValueError(f"{what} {str(path)!r}: OpenCV cannot write this file type")


def write_like(path, values, dtype):
    """Round ``values`` to ``dtype`` (clipped to its range) and write the file."""
    dtype = np.dtype(dtype)
    out = np.clip(np.rint(values), 0, _DEPTHS[dtype]).astype(dtype)
    if not cv2.imwrite(str(path), out):
        raise ValueError(f"cannot write {str(path)!r}")
    return out
