"""``python -m evolution.deploy --from RUN_DIR --out DIR``: bundle a run's fittest agents."""

from __future__ import annotations

import argparse
import sys

from evolution.deploy import write_bundle


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m evolution.deploy",
        description="Write a deployment bundle (exported behaviours, controller weights, "
        "normalisation, version, plain-Python reference step) of the fittest agents of a run.",
    )
    parser.add_argument("--from", dest="source", required=True, help="run directory")
    parser.add_argument(
        "--generation", type=int, default=None, help="checkpoint generation (default: newest)"
    )
    parser.add_argument("--top", type=int, default=5, help="fittest agents to bundle")
    parser.add_argument("--out", required=True, help="bundle directory")
    args = parser.parse_args(argv)
    from evolution.api import CHECKPOINT_DIR
    from evolution.experiment import policies_for_identity, read_run_record
    from evolution.runner import EvolutionRunner, latest_checkpoint
    from evolution.transfer import (
        checkpoint_of_generation,
        fittest_individuals,
        ranked_generation,
    )

    try:
        record = read_run_record(args.source)
        if args.generation is None:
            checkpoint = latest_checkpoint(f"{args.source}/{CHECKPOINT_DIR}")
            if checkpoint is None:
                raise ValueError(f"{args.source} has no checkpoint")
        else:
            checkpoint = checkpoint_of_generation(args.source, args.generation)
        policies = policies_for_identity(record["policies"])
        with EvolutionRunner.from_checkpoint(checkpoint, policies) as runner:
            generation = int(checkpoint.stem.split("_")[1])
            chosen = fittest_individuals(runner.scheduler, args.top, ranked_generation(generation))
            evo = runner.config.evolution
        provenance = {
            "run": str(args.source),
            "checkpoint": checkpoint.name,
            "fitness": [c.fitness for c in chosen],
            "mated": [c.mated for c in chosen],
        }
        path = write_bundle(
            args.out, [c.genome for c in chosen], max_energy=evo.max_energy,
            max_recharge_steps=evo.max_recharge_steps, provenance=provenance,
        )  # fmt: skip
    except (OSError, ValueError) as err:
        print(f"evolution.deploy: error: {err}", file=sys.stderr)
        return 2
    print(f"wrote bundle {path} ({len(chosen)} agents from {checkpoint.name})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
