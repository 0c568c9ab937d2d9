"""``cyber-rodent render``: an MP4 continuing a run from one of its checkpoints."""

from __future__ import annotations

import argparse

from evolution.cli.parsing import CliError, int_arg

HELP = "render an MP4 video continuing a run"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = (
        "Render an MP4 continuing a run from its newest checkpoint (or the "
        "checkpoint of generation --start, or a given checkpoint file): the top-down field "
        "with robot labels (CRi = robot i), heading arrows, docking and mating marks, the "
        "robots' omni camera strips, and a legend of every colour and mark in each frame. "
        "The run directory is not modified."
    )
    parser.add_argument("dir", nargs="?", default=None, help="a run directory")
    parser.add_argument("--checkpoint", default=None, help="a checkpoint file instead")
    parser.add_argument("--out", required=True, help="output .mp4 file")
    parser.add_argument(
        "--frames",
        default="300",
        metavar="N",
        help="number of frames, in [1, 100000] (one control step each by default; 300 = 30 s "
        "at 10 fps)",
    )
    parser.add_argument(
        "--size",
        default=None,
        metavar="WxH",
        help="frame size in px (default 1280x720): even W and H, H in [480, 2160], W in "
        "[H + 256, 3840]",
    )
    parser.add_argument(
        "--camera",
        default="top",
        metavar="VIEW",
        help="top (field from above + every robot's omni strip; the default), chase:N (robot "
        "N's chase view) or omni:N (robot N's omni strip across the frame); N a robot index",
    )
    parser.add_argument(
        "--start",
        default=None,
        metavar="G",
        help="begin where generation G closed, from the run directory's checkpoint of "
        "generation G (default: the newest checkpoint; evolve with --keep-checkpoints 0 to "
        "keep every generation)",
    )
    parser.add_argument(
        "--fps",
        type=int_arg("--fps"),
        default=10,
        help="frames per second of the MP4, 1-120 (default 10). A frame is drawn every "
        "--steps-per-frame control steps of 0.2 s, so with 1 step per frame 5 fps plays in "
        "real time and 10 fps at twice real time",
    )
    parser.add_argument(
        "--steps-per-frame",
        type=int_arg("--steps-per-frame"),
        default=1,
        help="control steps simulated between two frames, 1-1000 (default 1); raise it to "
        "show more of a run in a shorter video",
    )
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def run(args: argparse.Namespace) -> int:
    from evolution.lab import experiment, video

    if (args.dir is None) == (args.checkpoint is None):
        raise CliError("give a run directory or --checkpoint FILE (one of them)")
    # Every option is checked (one line naming it and its range) before any file is written.
    default = video.VideoConfig()
    width, height = (
        (default.width, default.height) if args.size is None else video.parse_size(args.size)
    )
    camera = video.parse_camera(args.camera)
    frames = video.parse_integer_option("--frames", args.frames, 1, video.MAX_FRAMES)
    source = args.dir if args.dir is not None else args.checkpoint
    if args.start is not None:
        start = video.parse_integer_option("--start", args.start, 0, float("inf"))
        if args.dir is None:
            raise CliError("--start picks a run directory's checkpoint; give DIR, not --checkpoint")
        source = video.start_checkpoint(args.dir, start)
    robots = video.run_robot_count(source)
    if robots is not None:  # else the video checks it once the checkpoint is loaded
        video.check_camera_robot(camera, robots)
    out = experiment.render_run(
        source,
        args.out,
        frames=frames,
        fps=args.fps,
        steps_per_frame=args.steps_per_frame,
        progress=not args.no_progress,
        width=width,
        height=height,
        camera=str(camera),
    )
    print(f"wrote {out}")
    return 0
