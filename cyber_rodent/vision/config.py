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

import dataclasses
import math
from dataclasses import dataclass, field

from cyber_rodent.validation import check_integer, integer, number, validate_fields
from cyber_rodent.vision.types import CLASS_NAMES, DEFAULT_MAX_DISTANCE, N_CLASSES

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
        # No field defaults (every colour names its box), so the rules are checked here.
        for name in ("hue_low", "hue_high"):
            check_integer(name, getattr(self, name), 0, 179)
        for name in ("sat_min", "val_min"):
            check_integer(name, getattr(self, name), 0, 255)


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

    bearing_std_deg: float = number(0.0, 0.0, 90.0, unit="deg", source="docs/design.md §9.24")
    distance_rel_std: float = number(0.0, 0.0, 1.0, source="docs/design.md §9.24")
    dropout: float = number(0.0, 0.0, 1.0, unit="probability", source="docs/design.md §9.24")

    def __post_init__(self) -> None:
        validate_fields(self)

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
            Default: the field's diagonal, so the camera's resolution is the real limit:
            3.25 m in the paper's 2.3 m field; a run in another field
            (``world.field_size``) gets that field's diagonal (:func:`follow_field`).
        min_blob_area: pixels, per class (LED, FACE, BATTERY); smaller colour blobs are
            ignored, and the geometric provider applies the same threshold to a target's
            expected visible area. Nothing but an LED is green, so one pixel is an LED; red and
            blue blobs of one or two pixels are mostly fragments of a face or pack glimpsed
            through a gap (under a chassis, beside a wheel), whose edges give no distance,
            while a whole pack anywhere in the field covers at least ~5 pixels by default.
        trace_below: pixels, per class (LED, FACE, BATTERY): the geometric provider measures
            a target whose whole footprint covers fewer pixels than this pixel by pixel (a ray
            through each covered pixel centre) when, reading its occlusion samples in order,
            one is hidden before their estimate is certain and one is seen, so a small target
            that a nearer body partly hides is seen when enough of its pixels show; other
            targets keep the samples' estimate (footprint × visible share of samples). 0 turns
            it off for the class (the model before it). docs/design.md §6.
        led, face, battery: HSV thresholds of the three colour classes.
        noise: optional measurement noise (off by default).
        near_clip: m, OpenGL near plane of the views (must be inside the robot's own body).
    """

    n_views: int = integer(4, 3, 16, unit="views", source="docs/design.md §6")
    view_width: int = integer(128, 4, MAX_IMAGE_SIDE, unit="px", source="docs/design.md §6")
    height: int = integer(192, 4, MAX_IMAGE_SIDE, unit="px", source="docs/design.md §6")
    elevation_min_deg: float = number(
        -45.0, -80.0, 0.0, high_open=True, unit="deg", source="docs/design.md §9.20"
    )
    elevation_max_deg: float = number(3.0, 0.0, 60.0, unit="deg", source="docs/design.md §9.20")
    max_range: float = number(
        DEFAULT_MAX_DISTANCE, 0.0, 100.0, low_open=True, unit="m", source="docs/design.md §9.21"
    )
    min_blob_area: tuple[int, int, int] = (1, 3, 3)
    trace_below: tuple[int, int, int] = (48, 120, 120)
    led: ColourThreshold = GREEN_LED
    face: ColourThreshold = RED_FACE
    battery: ColourThreshold = BLUE_BATTERY
    noise: VisionNoise = field(default_factory=VisionNoise)
    near_clip: float = number(0.01, 0.001, 0.05, unit="m", source="docs/design.md §6")

    def __post_init__(self) -> None:
        validate_fields(self)
        check_integer(
            "n_views * view_width (the omni strip's width)", self.strip_width, 1, MAX_IMAGE_SIDE
        )
        area = self.min_blob_area
        if not isinstance(area, tuple) or len(area) != N_CLASSES:
            raise ValueError(
                "min_blob_area must be a tuple of 3 integers in [1, 10000] pixels (LED, FACE, "
                f"BATTERY), got {area!r}"
            )
        for name, a in zip(CLASS_NAMES, area, strict=True):
            check_integer(f"min_blob_area ({name})", a, 1, 10_000)
        trace = self.trace_below
        if not isinstance(trace, tuple) or len(trace) != N_CLASSES:
            raise ValueError(
                "trace_below must be a tuple of 3 integers in [0, 10000] pixels (LED, FACE, "
                f"BATTERY), got {trace!r}"
            )
        for name, a in zip(CLASS_NAMES, trace, strict=True):
            check_integer(f"trace_below ({name})", a, 0, 10_000)
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


def default_max_range(field_size: float) -> float:
    """The camera's default range in a square field of side ``field_size`` (m): the field's
    diagonal, so that the camera's resolution, not its range, limits what a robot sees
    (docs/design.md §9.21). The paper's 2.3 m field gives :data:`DEFAULT_MAX_DISTANCE`."""
    return field_size * math.sqrt(2)


def camera_for_field(field_size: float) -> CameraConfig:
    """The default camera in a square field of side ``field_size`` (m): its range is the
    field's diagonal (:func:`default_max_range`); in the paper's field, :class:`CameraConfig`'s
    defaults exactly."""
    return CameraConfig(max_range=default_max_range(field_size))


def follow_field(camera: CameraConfig, old_field: float, new_field: float) -> CameraConfig:
    """``camera`` moved from a field of side ``old_field`` to one of ``new_field`` (m).

    A range that is the old field's default (its diagonal, :func:`default_max_range`) becomes
    the new field's; a range set to anything else is the user's choice and is kept.
    """
    if new_field != old_field and camera.max_range == default_max_range(old_field):
        return dataclasses.replace(camera, max_range=default_max_range(new_field))
    return camera
