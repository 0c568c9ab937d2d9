"""MP4 videos of a run, rendered off-screen: the field from above plus every robot's omni view.

Each frame shows, on the left, the top-down field with each robot's label, energy bar, active
behaviour, LED and docking state, and a line between robots at the moment they exchange
genomes; on the right, every robot's 360° omni strip (what its camera sees, straight ahead in
the middle) under a status line (agent, generation, energy, behaviour). One frame per control
step at 5 fps is real time (a control step is 0.2 s by default).

The video continues the run from where the runner stands (for example, a run loaded from a
checkpoint) by stepping it; the run directory on disk is never modified. The MP4 (H.264 via
imageio-ffmpeg's bundled ffmpeg) is written to a temporary file and renamed when complete.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from cyber_rodent.atomic import atomic_output
from cyber_rodent.render import FieldRenderer, check_writable_output
from cyber_rodent.validation import integer, validate_fields
from cyber_rodent.vision import CameraConfig
from cyber_rodent.vision.rendering import OmniRenderer

if TYPE_CHECKING:
    from evolution.runner import EvolutionRunner

#: Behaviour index → (label, RGB colour) for overlays; -1 = recharging, no behaviour.
BEHAVIOUR_STYLE = {
    0: ("Mate", (60, 220, 60)),
    1: ("Forage", (70, 130, 255)),
    2: ("Search", (200, 200, 200)),
    -1: ("Recharge", (255, 200, 40)),
}
_FONT = cv2.FONT_HERSHEY_SIMPLEX
MAX_FRAMES = 100_000


@dataclass(frozen=True)
class VideoConfig:
    """How a video looks.

    Attributes:
        fps: frames per second of the MP4 (with ``steps_per_frame=1``, 5 is real time at the
            default 0.2 s control step, and the default 10 is twice real time).
        steps_per_frame: control steps between frames.
        field_px: side of the top-down view in pixels (a multiple of 16).
        mating_flash_frames: frames a mating line stays visible.
    """

    fps: int = integer(10, 1, 120)
    steps_per_frame: int = integer(1, 1, 1000)
    field_px: int = integer(720, 128, 2048)
    mating_flash_frames: int = integer(8, 0)

    def __post_init__(self) -> None:
        validate_fields(self)
        if self.field_px % 16:
            raise ValueError(
                f"field_px must be a multiple of 16 in [128, 2048], got {self.field_px!r}"
            )


class RunVideo:
    """Renders frames of a running :class:`EvolutionRunner`."""

    def __init__(self, runner: EvolutionRunner, config: VideoConfig | None = None):
        self.runner = runner
        self.config = config or VideoConfig()
        world = runner.world
        px = self.config.field_px
        self.field = FieldRenderer(world, px, px)
        self.camera = CameraConfig()
        self.omni = OmniRenderer(world, self.camera)
        n = world.config.n_robots
        self.n = n
        # Right column: one strip per robot, scaled to the column width, plus a status line.
        from cyber_rodent.vision.projection import OmniProjection

        proj = OmniProjection(self.camera)
        self._recentre = self.camera.strip_width // 2 - int(np.argmin(np.abs(proj.column_bearing)))
        # Scale so that a pixel spans the same angle both ways (the strip reads as a panorama).
        aspect = proj.px_per_v / proj.px_per_u
        self.strip_w = px
        self.strip_h = max(16, round(px * self.camera.height / aspect / self.camera.strip_width))
        self.status_h = 22
        panel = n * (self.strip_h + self.status_h)
        self.height = max(px, (panel + 15) // 16 * 16)
        self.width = 2 * px
        self._flash: list[tuple[int, int, int]] = []  # (robot a, robot b, frames left)

    def advance(self) -> None:
        """Step the run by ``steps_per_frame`` control steps, remembering matings to draw."""
        survival = self.runner.survival
        for _ in range(self.config.steps_per_frame):
            self.runner.step()
            partner = survival.events.mate_partner
            for a in np.flatnonzero(partner >= 0).tolist():
                b = int(partner[a])
                if a < b:
                    self._flash.append((a, b, self.config.mating_flash_frames))

    def frame(self) -> np.ndarray:
        """The current frame, (height, width, 3) uint8 RGB."""
        out = np.zeros((self.height, self.width, 3), dtype=np.uint8)
        px = self.config.field_px
        out[:px, :px] = self._field_panel()
        strips = self.omni.render()
        y = 0
        for i in range(self.n):
            out[y : y + self.status_h, px:] = self._status_line(i)
            y += self.status_h
            strip = np.roll(strips[i], self._recentre, axis=1)
            out[y : y + self.strip_h, px:] = cv2.resize(
                strip, (self.strip_w, self.strip_h), interpolation=cv2.INTER_AREA
            )
            y += self.strip_h
        return out

    def _behaviour(self) -> np.ndarray:
        runner = self.runner
        shown = runner.controller.behaviour.astype(np.int64)  # the last step's choice
        shown[runner.survival.docked] = -1
        return shown

    def _field_panel(self) -> np.ndarray:
        runner, world = self.runner, self.runner.world
        image = np.ascontiguousarray(self.field.top_down())
        poses = world.poses()
        top = np.column_stack([poses[:, :2], np.full(self.n, 0.17)])
        pix = self.field.project_top_down(top).round().astype(int)
        behaviour = self._behaviour()
        max_energy = runner.survival.config.max_energy
        for a, b, _ in self._flash:
            cv2.line(image, tuple(pix[a]), tuple(pix[b]), (255, 60, 200), 3, cv2.LINE_AA)
        self._flash = [(a, b, k - 1) for a, b, k in self._flash if k > 1]
        for i in range(self.n):
            x, y = pix[i]
            label, colour = BEHAVIOUR_STYLE[int(behaviour[i])]
            if runner.survival.docked[i]:
                cv2.circle(image, (x, y), 34, (255, 200, 40), 2, cv2.LINE_AA)
            energy = float(runner.survival.energy[i]) / max_energy
            x0, y0 = x - 28, y - 44
            cv2.rectangle(image, (x0, y0), (x0 + 56, y0 + 7), (40, 40, 40), -1)
            bar = (60, 200, 60) if energy > 0.25 else (230, 60, 40)
            cv2.rectangle(image, (x0, y0), (x0 + int(56 * energy), y0 + 7), bar, -1)
            cv2.putText(
                image, f"CR{i + 1} {label}", (x - 30, y + 48), _FONT, 0.45, colour, 2, cv2.LINE_AA
            )
        t = world.data.time
        cv2.rectangle(image, (0, 0), (430, 34), (20, 20, 20), -1)
        cv2.putText(
            image,
            f"t = {t:7.1f} s   generation {runner.completed_generations}",
            (12, 24),
            _FONT,
            0.6,
            (255, 255, 255),
            2,
            cv2.LINE_AA,
        )
        return image

    def _status_line(self, i: int) -> np.ndarray:
        runner = self.runner
        line = np.full((self.status_h, self.strip_w, 3), 24, dtype=np.uint8)
        sched = runner.scheduler
        slot = int(sched.active_slot[i])
        generation = int(sched.slot_generation[i, slot])
        label, colour = BEHAVIOUR_STYLE[int(self._behaviour()[i])]
        led = "LED on" if runner.world.led_on[i] else "LED off"
        text = (
            f"CR{i + 1}  agent {slot:2d}  gen {generation:3d}  "
            f"energy {runner.survival.energy[i]:5.0f}  {label:8s} {led}"
        )
        cv2.putText(line, text, (6, 16), _FONT, 0.5, colour, 1, cv2.LINE_AA)
        return line

    def close(self) -> None:
        self.field.close()
        self.omni.close()


def render_video(
    runner: EvolutionRunner,
    out_path: str | os.PathLike[str],
    frames: int,
    config: VideoConfig | None = None,
    progress: bool = True,
) -> Path:
    """Continue ``runner`` for ``frames`` frames and write them as an MP4.

    Raises:
        ValueError: a bad frame count or config, or an unwritable output path (checked before
            anything is rendered).
    """
    import imageio.v2 as imageio

    if isinstance(frames, bool) or not isinstance(frames, int) or not 1 <= frames <= MAX_FRAMES:
        raise ValueError(f"frames must be an integer in [1, {MAX_FRAMES}], got {frames!r}")
    config = config or VideoConfig()
    out = check_writable_output(out_path)
    if out.suffix.lower() != ".mp4":
        raise ValueError(f"video output must be an .mp4 file, got {out.name}")
    video = RunVideo(runner, config)
    try:
        with atomic_output(out) as temp:
            writer = imageio.get_writer(
                str(temp),
                format="FFMPEG",
                fps=config.fps,
                codec="libx264",
                quality=7,
                macro_block_size=16,
                pixelformat="yuv420p",
            )
            bar = None
            if progress:
                from tqdm.auto import tqdm

                bar = tqdm(
                    total=frames, unit="frame", desc=f"render {out.name}", dynamic_ncols=True
                )
            try:
                for _ in range(frames):
                    video.advance()
                    writer.append_data(video.frame())
                    if bar is not None:
                        bar.update()
            finally:
                writer.close()
                if bar is not None:
                    bar.close()
    finally:
        video.close()
    return out
