"""Configuration of the omnidirectional camera, its colour segmentation and its noise model.

One frozen :class:`CameraConfig` describes the camera for *both* providers, so that the
geometric fast path and the rendered camera see the same field of view, range and resolution
(the geometric provider uses the resolution to decide whether a target is large enough to form a
blob). Every number the vision code uses is a field here; the target geometry (LED, face and
pack sizes, camera height) is read from the compiled MuJoCo model, not repeated.

Field of view (a choice the paper leaves open, docs/design.md §6): the CR's omni camera sees
360° horizontally and a limited elevation band. We render ``n_views`` pinhole views (90° each
by default) whose
image planes are vertical (no tilt) but whose frustum is shifted downwards (a lens shift). An
untilted sensor keeps every pixel column at one bearing, as the radial lines of a real
catadioptric omni image do, which makes bearing a pure column lookup. The default band is from
45° below to 3° above the horizon, guaranteed at every bearing (the frustum is widened by the
corner factor ``sqrt(1 + tan²(π/n))``, so view centres see a little further down, to 54.7°):

* everything the robot must see is below the camera (LED 6 cm, face 10 cm, pack top 7 cm
  lower), so the horizon plus a 3° margin is the top;
* 45° down covers the top of a pack touching the robot's side (0.115 m from the camera axis,
  top at 24°–43°), another robot's LED side by side (≥ 0.118 m, ≤ 27°) and a face nose to nose
  (≥ 0.16 m, ≤ 36°); a docked pack's top is at 18°–27°.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from cyber_rodent.vision.types import DEFAULT_MAX_DISTANCE, N_CLASSES

#: The largest image dimension we accept (pixels per view horizontally, or rows). The render
#: buffer must hold every robot's strip; OpenGL renderbuffers of Mesa llvmpipe stop at 16384.
MAX_IMAGE_SIDE = 4096
#: Largest number of pixels of all robots' strips together (one render buffer).
MAX_BUFFER_PIXELS = 32 * 1024 * 1024


@dataclass(frozen=True)
class ColourThreshold:
    """An HSV box in OpenCV's convention (hue 0–179, saturation and value 0–255).

    A pixel is of this colour when its hue is in [``hue_low``, ``hue_high``] (the interval wraps
    around 180 when ``hue_low > hue_high``, which red needs), its saturation is at least
    ``sat_min`` and its value at least ``val_min``.
    """

    hue_low: int
    hue_high: int
    sat_min: int
    val_min: int

    def __post_init__(self) -> None:
        for name in ("hue_low", "hue_high"):
            v = getattr(self, name)
            if not isinstance(v, int) or not 0 <= v <= 179:
                raise ValueError(f"{name} must be an integer in [0, 179] (OpenCV hue), got {v!r}")
        for name in ("sat_min", "val_min"):
            v = getattr(self, name)
            if not isinstance(v, int) or not 0 <= v <= 255:
                raise ValueError(f"{name} must be an integer in [0, 255], got {v!r}")


# Colours in the scene (see assets/mjcf): LED on (0.1, 1, 0.1) → hue 60; LED off is dark green
# (value ≈ 0.15 before lighting) and must fall below val_min; face (0.9, 0.05, 0.05) → hue 0;
# pack (0.05, 0.15, 0.9) → hue ≈ 113. Walls, floor and bodies are unsaturated (S < 0.1).
GREEN_LED = ColourThreshold(hue_low=45, hue_high=75, sat_min=150, val_min=110)
RED_FACE = ColourThreshold(hue_low=172, hue_high=8, sat_min=150, val_min=70)
BLUE_BATTERY = ColourThreshold(hue_low=100, hue_high=125, sat_min=150, val_min=60)


@dataclass(frozen=True)
class VisionNoise:
    """Optional measurement noise of the vision output (for sim-to-real studies; off by default).

    Applied per detected target, before the nearest target of a class is chosen, so a noisy
    measurement can change which target counts as nearest, as on the real robot.

    Attributes:
        bearing_std_deg: std of additive Gaussian bearing noise, degrees.
        distance_rel_std: std of multiplicative Gaussian distance noise (0.1 = 10 %).
        dropout: probability that a visible target is missed in a frame.
    """

    bearing_std_deg: float = 0.0
    distance_rel_std: float = 0.0
    dropout: float = 0.0

    def __post_init__(self) -> None:
        if not (_is_real(self.bearing_std_deg) and 0.0 <= self.bearing_std_deg <= 90.0):
            raise ValueError(
                f"bearing_std_deg must be in [0, 90] degrees, got {self.bearing_std_deg!r}"
            )
        if not (_is_real(self.distance_rel_std) and 0.0 <= self.distance_rel_std <= 1.0):
            raise ValueError(f"distance_rel_std must be in [0, 1], got {self.distance_rel_std!r}")
        if not (_is_real(self.dropout) and 0.0 <= self.dropout <= 1.0):
            raise ValueError(f"dropout must be a probability in [0, 1], got {self.dropout!r}")

    @property
    def enabled(self) -> bool:
        return self.bearing_std_deg > 0 or self.distance_rel_std > 0 or self.dropout > 0


@dataclass(frozen=True)
class CameraConfig:
    """The omnidirectional camera of one CR (identical for every robot).

    Attributes:
        n_views: pinhole views that tile the 360° (each covers 360°/n_views horizontally).
        view_width: pixel columns per view.
        height: pixel rows of the omni strip. Pixels need not be square: the LED ring is wide
            and flat (4.4 cm × 1.4 cm), so vertical resolution buys detection range cheaper
            than horizontal resolution. The default 128 × 192 per view detects another
            robot's LED in every trial out to 2.0 m (70-90 % at 2.25-2.5 m); 64 × 96 only to
            1.0 m, 96 × 144 to 1.5 m, 128 × 256 to the 2.5 m tested. Rendering and segmenting
            all 4 robots costs ~18 ms per control step at the default, ~12 ms at 64 × 96, and
            ~20 ms at 128 × 256 on 2 llvmpipe cores: the per-tile cost dominates, not the
            pixels (``benchmarks/vision_cost.py``).
        elevation_min_deg: lowest elevation (negative = below the horizon) seen at every bearing.
        elevation_max_deg: highest elevation seen at every bearing (≥ 0: the horizon is in view).
        max_range: m, targets farther than this (horizontal distance) are not reported.
            Default: the field's diagonal, i.e. the camera's resolution is the real limit.
        min_blob_area: pixels, per class (LED, FACE, BATTERY); smaller colour blobs are
            ignored, and the geometric provider applies the same threshold to a target's
            expected visible area. Nothing but an LED is green, so one pixel is an LED; red and
            blue blobs of one or two pixels are mostly fragments of a face or pack glimpsed
            through a gap (under a chassis, beside a wheel), whose edges give no distance,
            while a whole pack anywhere in the field covers at least ~5 pixels by default.
        led, face, battery: HSV thresholds of the three colour classes.
        noise: optional measurement noise (off by default).
        near_clip: m, OpenGL near plane of the views (must be inside the robot's own body).
    """

    n_views: int = 4
    view_width: int = 128
    height: int = 192
    elevation_min_deg: float = -45.0
    elevation_max_deg: float = 3.0
    max_range: float = DEFAULT_MAX_DISTANCE
    min_blob_area: tuple[int, int, int] = (1, 3, 3)
    led: ColourThreshold = GREEN_LED
    face: ColourThreshold = RED_FACE
    battery: ColourThreshold = BLUE_BATTERY
    noise: VisionNoise = field(default_factory=VisionNoise)
    near_clip: float = 0.01

    def __post_init__(self) -> None:
        if not isinstance(self.n_views, int) or not 3 <= self.n_views <= 16:
            raise ValueError(f"n_views must be an integer in [3, 16], got {self.n_views!r}")
        for name, lo in (("view_width", 4), ("height", 4)):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or not lo <= v <= MAX_IMAGE_SIDE:
                raise ValueError(
                    f"{name} must be an integer number of pixels in [{lo}, {MAX_IMAGE_SIDE}], "
                    f"got {v!r}"
                )
        if self.n_views * self.view_width > MAX_IMAGE_SIDE:
            raise ValueError(
                f"n_views * view_width (the omni strip's width) must be at most "
                f"{MAX_IMAGE_SIDE} pixels, got {self.n_views * self.view_width}"
            )
        if not (_is_real(self.elevation_min_deg) and -80.0 <= self.elevation_min_deg < 0.0):
            raise ValueError(
                f"elevation_min_deg must be in [-80, 0) degrees, got {self.elevation_min_deg!r}"
            )
        if not (_is_real(self.elevation_max_deg) and 0.0 <= self.elevation_max_deg <= 60.0):
            raise ValueError(
                f"elevation_max_deg must be in [0, 60] degrees, got {self.elevation_max_deg!r}"
            )
        if not (_is_real(self.max_range) and 0.0 < self.max_range <= 100.0):
            raise ValueError(f"max_range must be in (0, 100] m, got {self.max_range!r}")
        area = self.min_blob_area
        if not (
            isinstance(area, tuple)
            and len(area) == N_CLASSES
            and all(
                isinstance(a, int) and not isinstance(a, bool) and 1 <= a <= 10_000 for a in area
            )
        ):
            raise ValueError(
                "min_blob_area must be a tuple of 3 integers in [1, 10000] pixels (LED, FACE, "
                f"BATTERY), got {area!r}"
            )
        if not (_is_real(self.near_clip) and 0.001 <= self.near_clip <= 0.05):
            raise ValueError(f"near_clip must be in [0.001, 0.05] m, got {self.near_clip!r}")
        for name in ("led", "face", "battery"):
            if not isinstance(getattr(self, name), ColourThreshold):
                raise ValueError(f"{name} must be a ColourThreshold")
        if not isinstance(self.noise, VisionNoise):
            raise ValueError("noise must be a VisionNoise")

    @property
    def thresholds(self) -> tuple[ColourThreshold, ColourThreshold, ColourThreshold]:
        """The HSV thresholds in class order (LED, FACE, BATTERY)."""
        return (self.led, self.face, self.battery)

    @property
    def strip_width(self) -> int:
        """Pixel columns of one robot's 360° strip."""
        return self.n_views * self.view_width


def _is_real(v: object) -> bool:
    return isinstance(v, float | int) and not isinstance(v, bool) and math.isfinite(v)
