"""``python -m evolution.lab.deploy --from RUN_DIR --out DIR``: bundle a run's fittest mated agents.

:func:`add_arguments` and :func:`run` are the command's two halves, so another command line
(``cyber-rodent``) can mount it as a subcommand; :func:`main` is the standalone program. Every
option is checked before anything is written; a bad one prints one line naming the option and
its allowed values and exits with status 2.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from evolution.lab.api import CHECKPOINT_DIR
from evolution.lab.deploy import check_bundle_dir, write_bundle
from evolution.lab.deploy.selection import choose_agents, ranked_candidates
from evolution.lab.experiment import policies_for_identity, read_run_record
from evolution.lab.transfer import checkpoint_of_generation, ranked_generation
from evolution.runner import EvolutionRunner, latest_checkpoint

#: Exit status of every user error.
EXIT_USAGE = 2
DEFAULT_TOP = 5


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the command's options to ``parser`` (the numbers are checked by :func:`run`)."""
    parser.add_argument(
        "--from", dest="source", required=True, metavar="RUN_DIR",
        help="run directory (run.json and checkpoints/)",
    )  # fmt: skip
    parser.add_argument(
        "--generation", default=None, metavar="G",
        help="checkpoint generation, an integer >= 0 the run kept (default: the newest)",
    )  # fmt: skip
    parser.add_argument(
        "--top", default=DEFAULT_TOP, metavar="N",
        help=f"fittest agents to bundle, an integer >= 1 (default {DEFAULT_TOP}); only agents "
        "that mated qualify, and fewer are bundled if fewer did",
    )  # fmt: skip
    parser.add_argument(
        "--include-unmated", action="store_true",
        help="let agents that never mated qualify too (the plain fitness ranking)",
    )  # fmt: skip
    parser.add_argument(
        "--portable-only", action="store_true",
        help="leave out the .pt2 programs and the action values: the behaviours' greedy tables "
        "only (a few kB; needs no torch to write or to run)",
    )  # fmt: skip
    parser.add_argument(
        "--out", required=True, metavar="DIR",
        help="bundle directory: new, empty, or an earlier bundle to replace",
    )  # fmt: skip
    parser.set_defaults(deploy_prog=parser.prog)


def _integer(option: str, value: Any, low: int, high: int | None = None) -> int:
    """``value`` (an int, or its text from the command line) as an int in [low, high]."""
    allowed = f"[{low}, {high}]" if high is not None else f"[{low}, ∞)"
    try:
        number = value if isinstance(value, int) and not isinstance(value, bool) else int(value)
    except (TypeError, ValueError):
        number = None
    if number is None or number < low or (high is not None and number > high):
        raise ValueError(f"{option} must be an integer in {allowed}, got {value!r}")
    return number


def run(args: argparse.Namespace) -> int:
    """Write the bundle the options describe; 0 on success, 2 (one line on stderr) on bad input.

    Options are checked in order before any file or directory is created: ``--top`` and
    ``--generation`` are integers, ``--out`` may receive a bundle, ``--from`` is a run with
    that checkpoint, ``--top`` does not exceed the agents ranked, and at least one agent
    qualifies.
    """
    prog = getattr(args, "deploy_prog", "evolution.lab.deploy")
    try:
        return _run(args, prog)
    except (OSError, ValueError) as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        return EXIT_USAGE


def _run(args: argparse.Namespace, prog: str) -> int:
    from pathlib import Path

    from behaviours.greedy_policy import GreedyPolicy
    from behaviours.inputs import BEHAVIOUR_NAMES

    top = _integer("--top", args.top, 1)
    generation = None if args.generation is None else _integer("--generation", args.generation, 0)
    out = check_bundle_dir(args.out, "--out")
    source = Path(args.source)
    try:
        record = read_run_record(source)
    except ValueError as err:
        raise ValueError(f"--from: {err}") from None
    learning = record.get("config", {}).get("evolution", {}).get("learning", {})
    if isinstance(learning, dict) and learning.get("enabled"):
        raise ValueError(
            f"--from: {source} is a learning-mode run: its agents act on values they learned "
            "in their lives, which a bundle does not carry; deploy takes runs of the fixed "
            "behaviours"
        )
    if generation is None:
        checkpoint = latest_checkpoint(source / CHECKPOINT_DIR)
        if checkpoint is None:
            raise ValueError(f"--from: {source} has no checkpoint")
    else:
        try:
            checkpoint = checkpoint_of_generation(source, generation)
        except ValueError as err:
            raise ValueError(f"--generation: {err}") from None
    policies = policies_for_identity(record["policies"])
    greedy = [p for p in policies.policies if isinstance(p, GreedyPolicy)]
    if len(greedy) != len(BEHAVIOUR_NAMES):
        raise ValueError(
            f"--from: {source} ran the {policies.kind} behaviours; only learned (tile-coded) "
            "behaviours can be exported"
        )
    with EvolutionRunner.from_checkpoint(checkpoint, policies) as runner:
        checkpoint_generation = int(checkpoint.stem.split("_")[1])
        candidates, what = ranked_candidates(
            runner.scheduler, ranked_generation(checkpoint_generation)
        )
        config = runner.config
    if top > len(candidates):
        raise ValueError(
            f"--top must be an integer in [1, {len(candidates)}] ({what} of "
            f"{checkpoint.name}), got {top}"
        )
    selection = choose_agents(
        candidates, top, include_unmated=args.include_unmated, source=what
    )
    if not selection.agents:
        raise ValueError(
            f"none of the {selection.ranked} agents ranked ({what} of {checkpoint.name}) has "
            "mated; choose a later --generation, or pass --include-unmated"
        )
    agents = [
        {"fitness": a.fitness, "mated": a.mated, "robot": a.robot, "slot": a.slot}
        for a in selection.agents
    ]
    provenance = {
        "run": str(source),
        "checkpoint": checkpoint.name,
        "generation": checkpoint_generation,
        "policies": record["policies"],
        "seed": record.get("seed"),
        "method": (record.get("config") or {}).get("method"),
        "versions": record.get("versions"),
        "agents": agents,
    }
    chosen = {
        "mated_only": not selection.include_unmated,
        "requested": selection.requested,
        "bundled": len(selection.agents),
        "ranked": selection.ranked,
        "mated": selection.mated,
        "source": selection.source,
        "note": selection.note(),
    }
    values = {name: p.values for name, p in zip(BEHAVIOUR_NAMES, greedy, strict=True)}
    portable_only = bool(getattr(args, "portable_only", False))
    path = write_bundle(
        out, [a.genome for a in selection.agents], config=config, values=values,
        selection=chosen, provenance=provenance, programs=not portable_only,
        action_values=not portable_only,
    )  # fmt: skip
    if selection.short:
        print(f"{prog}: note: {selection.note()}")
    print(f"wrote bundle {path} ({len(selection.agents)} agents from {checkpoint.name})")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m evolution.lab.deploy",
        description="Write a deployment bundle (the behaviours exported and in a portable form, "
        "controller weights, recorded test vectors, the robot's conventions and survival "
        "bookkeeping in bundle.json and README.md, a plain numpy reference step with --check) "
        "of the fittest agents of a run that mated.",
    )
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
