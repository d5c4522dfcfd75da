"""Occupancy images with the ROS map_server thresholds.

A pixel's occupancy is p = (255 - v) / 255 for its luminance v (v / 255 when negated); it is
free iff p < free_thresh. Occupied (p > occupied_thresh) and unknown pixels are both obstacles:
a robot must not plan through space nobody has seen. Pillow decodes every common format
(PGM, PNG, BMP, TIFF, ...) and does the RGB-to-luminance conversion (ITU-R 601-2 luma).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from planner.errors import MapFormatError
from planner.types import BoolArray

if TYPE_CHECKING:  # the images come from planner.maps.files, which imports Pillow when needed
    from PIL import Image


@dataclass(frozen=True)
class Thresholds:
    """ROS map_server's interpretation of pixel values; the defaults are map_server's.

    Only ``free`` decides free versus blocked; ``occupied`` is kept so the YAML's meaning is
    recorded whole (it separates occupied from unknown, which are both obstacles here).
    """

    occupied: float = 0.65
    free: float = 0.196
    negate: bool = False


ROS_DEFAULTS = Thresholds()


def _luminance(image: Image.Image, source: str) -> tuple[np.ndarray, float]:
    """Luminance values and their full-scale value (255, or 65535 for 16-bit images)."""
    if image.mode.startswith("I;16") or image.mode == "I":
        return np.clip(np.asarray(image, dtype=np.float64), 0, 65535), 65535.0
    if image.mode == "F":
        raise MapFormatError(source, "floating-point images are not occupancy maps; "
                             "expected 8- or 16-bit grey, RGB(A) or palette")
    return np.asarray(image.convert("L"), dtype=np.float64), 255.0


def _opaque(image: Image.Image) -> BoolArray | None:
    """False where the pixel is fully transparent; None when the image has no alpha."""
    has_alpha = image.mode in ("RGBA", "LA", "PA") or (
        image.mode in ("P", "L", "RGB") and "transparency" in image.info)
    if not has_alpha:
        return None
    alpha = np.asarray(image.convert("RGBA"))[:, :, 3]
    return np.asarray(alpha > 0)


def free_pixels(image: Image.Image, thresholds: Thresholds, source: str) -> BoolArray:
    """Per-pixel free mask: free iff occupancy < free threshold and not transparent."""
    value, full = _luminance(image, source)
    # (full - v) / full exactly as map_server computes it, so values on a threshold agree.
    occupancy = value / full if thresholds.negate else (full - value) / full
    free = np.asarray(occupancy < thresholds.free)
    opaque = _opaque(image)
    if opaque is not None:
        free &= opaque
    return free
