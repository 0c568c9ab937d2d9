"""From per-target detections to a :class:`VisionFrame`, with the optional noise model.

Both providers reduce what they see to flat arrays of detections (robot, class, bearing,
distance, area). This module applies the same noise model and the same "nearest target of each
class" rule to both, so the providers can differ only in how they measure.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cyber_rodent.vision.config import VisionNoise
from cyber_rodent.vision.projection import wrap_angle
from cyber_rodent.vision.types import N_CLASSES, Blob, VisionFrame


def apply_noise(
    noise: VisionNoise,
    rng: np.random.Generator | None,
    bearing: np.ndarray,
    distance: np.ndarray,
    keep: np.ndarray,
) -> None:
    """Perturb detections in place: Gaussian bearing noise, multiplicative Gaussian distance
    noise (clipped at 0) and dropout (clears ``keep``). A no-op when the noise is off.

    Draws happen for every detection slot passed in, visible or not, so the random stream
    depends only on the array shapes, never on what happened to be visible.
    """
    if not noise.enabled:
        return
    if rng is None:
        raise ValueError("a vision noise model is configured, so pass rng=np.random.Generator")
    shape = bearing.shape
    if noise.bearing_std_deg > 0:
        bearing += rng.normal(0.0, math.radians(noise.bearing_std_deg), size=shape)
        bearing[...] = wrap_angle(bearing)
    if noise.distance_rel_std > 0:
        distance *= 1.0 + rng.normal(0.0, noise.distance_rel_std, size=shape)
        np.maximum(distance, 0.0, out=distance)
    if noise.dropout > 0:
        keep &= rng.random(size=shape) >= noise.dropout


def noise_state(rng: np.random.Generator | None) -> dict[str, Any]:
    """A vision provider's checkpoint state: its noise generator's state (None without noise).

    The noise generator is a provider's only state a resumed run needs: every other buffer is
    an output, overwritten by the next call before anyone reads it.
    """
    return {"rng": None if rng is None else rng.bit_generator.state}


def load_noise_state(rng: np.random.Generator | None, state: dict[str, Any]) -> None:
    """Restore a :func:`noise_state` into ``rng`` (the provider's noise generator).

    Raises:
        ValueError: the state has a generator and the provider none, or the other way round.
    """
    saved = state.get("rng")
    if (saved is None) != (rng is None):
        raise ValueError("vision state: the noise generator does not match this provider")
    if rng is not None and saved is not None:
        rng.bit_generator.state = dict(saved)


def frame_from_detections(
    n_robots: int,
    robot: np.ndarray,
    cls: np.ndarray,
    bearing: np.ndarray,
    distance: np.ndarray,
    area: np.ndarray,
) -> VisionFrame:
    """Build the frame: per robot and class the nearest detection, plus every blob.

    Args:
        n_robots: robots in the world.
        robot, cls, bearing, distance, area: flat (n_detections,) arrays, one entry per
            detected target.
    """
    frame = VisionFrame.empty(n_robots)
    if len(robot) == 0:
        return frame
    key = robot * N_CLASSES + cls
    order = np.lexsort((distance, key))
    key_sorted = key[order]
    first = np.ones(len(order), dtype=bool)
    first[1:] = key_sorted[1:] != key_sorted[:-1]
    nearest = order[first]
    r, c = robot[nearest], cls[nearest]
    frame.visible[r, c] = True
    frame.bearing[r, c] = bearing[nearest]
    frame.distance[r, c] = distance[nearest]
    blobs = frame.blobs
    for i, k, b, d, a in zip(
        robot.tolist(),
        cls.tolist(),
        bearing.tolist(),
        distance.tolist(),
        area.tolist(),
        strict=True,
    ):
        blobs[i].append(Blob(k, b, d, a))
    return frame
