"""The omni camera's projection: which bearing and elevation each pixel of the 360° strip sees.

One robot's omni image is a strip of ``n_views`` pinhole views side by side, left to right in
order of decreasing bearing, so the strip is continuous (and wraps around from its last column
to its first). View ``k`` looks along bearing ``π − 2πk/n``: for 4 views the tiles are back,
left, front, right (the views of the MJCF cameras ``omni_back``, ``omni_left``, ``omni_front``,
``omni_right``), and the columns run from bearing +225° (= −135°) to −135°, straight ahead at
the centre of the third tile. Each view has a vertical image plane with a downward lens shift (see
:mod:`cyber_rodent.vision.config`), so in view coordinates (x forward, y left, z up, all relative
to the camera) a point projects to

    u = -y / x  (image right),    v = z / x  (image up),

a column is one bearing (``view_centre - atan(u)``), and the horizontal distance of a point seen
at height ``z`` (relative to the camera) on image row ``v`` is ``z * sqrt(1 + u²) / v``.
Both providers use this one class, the rendered provider to read images, the geometric provider
to predict how many pixels a target covers.
"""

from __future__ import annotations

import math

import numpy as np

from cyber_rodent.vision.config import CameraConfig


class OmniProjection:
    """Pixel geometry of the omni strip for a :class:`CameraConfig`.

    Attributes:
        half_tan: tan of half a view's horizontal angle (tan 45° = 1 for 4 views).
        v_top, v_bottom: image-plane heights (tan units, at unit depth) of the strip's top and
            bottom edges; chosen so the configured elevation band is in view at every bearing.
        view_centres: (n_views,) rad, bearing of each view's optical axis, left to right.
        column_bearing: (strip_width,) rad in (-π, π], bearing of each pixel column's centre.
        column_u: (strip_width,) image-plane abscissa of each column's centre in its view.
        px_per_u, px_per_v: pixels per unit of u and of v.
    """

    def __init__(self, config: CameraConfig):
        self.config = config
        n, w, h = config.n_views, config.view_width, config.height
        self.half_tan = math.tan(math.pi / n)
        corner = math.sqrt(1.0 + self.half_tan**2)
        self.v_top = math.tan(math.radians(config.elevation_max_deg)) * corner
        self.v_bottom = math.tan(math.radians(config.elevation_min_deg)) * corner
        self.view_span = 2.0 * math.pi / n
        self.view_centres = math.pi - self.view_span * np.arange(n)
        self.px_per_u = w / (2.0 * self.half_tan)
        self.px_per_v = h / (self.v_top - self.v_bottom)
        cols = np.arange(w)
        u = -self.half_tan + (cols + 0.5) / self.px_per_u
        self.column_u = np.tile(u, n)
        self.column_view = np.repeat(np.arange(n), w)
        self.column_bearing = wrap_angle(
            self.view_centres[self.column_view] - np.arctan(self.column_u)
        )

    def v_at_row(self, y: np.ndarray | float) -> np.ndarray | float:
        """Image-plane height of continuous row coordinate ``y`` (0 = top edge of the strip)."""
        return self.v_top - np.asarray(y) / self.px_per_v

    def view_coordinates(self, bearing: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For bearings (rad, robot frame): the index of the view that sees them and the
        bearing relative to that view's axis (positive = left), in [-π/n, π/n)."""
        rel = np.mod(
            self.view_centres[0] - np.asarray(bearing) + 0.5 * self.view_span, 2.0 * math.pi
        )
        view = np.minimum((rel // self.view_span).astype(np.int64), self.config.n_views - 1)
        offset = 0.5 * self.view_span - (rel - view * self.view_span)
        return view, offset

    def horizontal_distance(
        self, height_below: np.ndarray, v: np.ndarray, u: np.ndarray
    ) -> np.ndarray:
        """Horizontal distance of a point ``height_below`` m below the camera seen at image
        coordinates (u, v) (v < 0 below the horizon); inf at or above the horizon."""
        v = np.asarray(v, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            d = np.asarray(height_below) * np.sqrt(1.0 + np.asarray(u) ** 2) / -v
        return np.where(v < 0, d, np.inf)


def wrap_angle(a: np.ndarray | float) -> np.ndarray:
    """Wrap angles to (-π, π]."""
    return np.pi - np.mod(np.pi - np.asarray(a), 2.0 * np.pi)
