"""``python -m evolution.lab.deploy.baseline --from RUN --generation G``: the colony's baseline.

Writes ``cyber_rodent/baseline/``, the data of the PettingZoo colony's ready policy
(:mod:`cyber_rodent.colony_baseline`): a deployment bundle of the run's fittest agents that
mated (``cyber-rodent deploy --portable-only``: ``bundle.json``, ``controller_weights.npy``, the
behaviours' greedy tables, ``test_vectors.npz``) without its ``README.md`` and
``reference_step.py`` (the package's step is :mod:`cyber_rodent.robot_step` itself), and
``baseline.json``: where the agents came from (the commands that made the run and the bundle,
the commit, the generation, the ranking rule) and how the colony assigns them.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
from pathlib import Path
from typing import Any

from cyber_rodent.atomic import write_json
from evolution.lab.deploy import BUNDLE_FILE, README_FILE, REFERENCE_FILE
from evolution.lab.deploy.__main__ import DEFAULT_TOP
from evolution.lab.deploy.__main__ import run as deploy
from evolution.lab.experiment import read_run_record

BASELINE_FILE = "baseline.json"
DEFAULT_OUT = "cyber_rodent/baseline"


def evolve_command(record: dict[str, Any], run_dir: str, generations: int) -> str:
    """The ``cyber-rodent evolve`` command that makes the run of ``record`` again."""
    config = record.get("config") or {}
    parts = ["cyber-rodent", "evolve", "--method", str(config.get("method")), "--seed",
             str(record.get("seed")), "--generations", str(generations),
             "--keep-checkpoints", "0"]  # fmt: skip
    for key, value in sorted((record.get("settings") or {}).items()):
        parts += ["--set", f"{key}={value}"]
    return shlex.join([*parts, "--out", run_dir])


def write_baseline(
    run_dir: str, generation: int, out: str = DEFAULT_OUT, top: int = DEFAULT_TOP
) -> Path:
    """Write the baseline (module docstring) from checkpoint ``generation`` of ``run_dir``.

    Raises:
        ValueError: the deploy command refused (its message on stderr).
    """
    args = argparse.Namespace(
        source=run_dir, generation=generation, top=top, include_unmated=False,
        portable_only=True, out=out, deploy_prog="python -m evolution.lab.deploy.baseline",
    )  # fmt: skip
    if deploy(args) != 0:
        raise ValueError(f"no baseline written from {run_dir} generation {generation}")
    root = Path(out)
    (root / README_FILE).unlink()
    (root / REFERENCE_FILE).unlink()
    spec = json.loads((root / BUNDLE_FILE).read_text())
    record = read_run_record(Path(run_dir))
    provenance, selection = spec["provenance"], spec["selection"]
    versions = provenance.get("versions") or {}
    n = spec["controller"]["n_agents"]
    command = evolve_command(record, run_dir, int(record["target_generations"]))
    write_json(root / BASELINE_FILE, {
        "what": "the PettingZoo colony's baseline policy (cyber_rodent.colony_env."
        "baseline_policy): agents evolved with embodied evolution over the shipped "
        "behaviours, run by cyber_rodent/robot_step.py on this bundle",
        "run": {
            "command": command,
            "commit": versions.get("git_commit"),
            "package_version": versions.get("cyber-rodent"),
            "method": provenance.get("method"),
            "seed": provenance.get("seed"),
            "policies": provenance.get("policies"),
        },
        "generation": provenance.get("generation"),
        "checkpoint": provenance.get("checkpoint"),
        "ranking": "the paper's fitness, batteries / (steps lived / 100), of the completed "
        "lives of the checkpoint's last closed generation, among the lives that mated, ties to "
        f"more matings (docs/design.md §9.25): {selection.get('note')}",
        "agents": provenance.get("agents"),
        "assignment": f"robot i of the colony runs row i mod {n} of controller_weights.npy "
        "(row 0 is the fittest); BaselinePolicy(env, agents=[...]) chooses others",
        "commands": [
            command,
            f"python -m evolution.lab.deploy.baseline --from {run_dir} --generation "
            f"{generation} --top {top} --out {out}",
        ],
        "files": "a cyber-rodent deploy --portable-only bundle without README.md and "
        "reference_step.py (the step is cyber_rodent/robot_step.py: python -m "
        f"cyber_rodent.robot_step --check --bundle {out})",
    })  # fmt: skip
    return root


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m evolution.lab.deploy.baseline",
        description="Write the PettingZoo colony's baseline bundle (cyber_rodent/baseline) "
        "from a run's checkpoint: its fittest agents that mated, the behaviours' greedy "
        "tables, test vectors and baseline.json (where the agents came from).",
    )
    parser.add_argument("--from", dest="source", required=True, metavar="RUN_DIR")
    parser.add_argument("--generation", required=True, type=int, metavar="G")
    parser.add_argument("--top", type=int, default=DEFAULT_TOP, metavar="N")
    parser.add_argument("--out", default=DEFAULT_OUT, metavar="DIR")
    args = parser.parse_args(argv)
    try:
        path = write_baseline(args.source, args.generation, args.out, args.top)
    except (OSError, ValueError) as err:
        print(f"{parser.prog}: error: {err}", file=sys.stderr)
        return 2
    print(f"wrote baseline {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
