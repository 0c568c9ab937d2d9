"""Export a learned greedy policy as a self-contained torch module for robot controllers.

A tile-coded linear Q is an embedding-bag sum: each action value is the sum, over the
``n_tilings`` active tiles, of one learned number per (tile, action). So the module is one
``nn.EmbeddingBag(table_size, n_actions, mode="sum")`` holding the weights, preceded by the tile
coder reimplemented in torch integer ops (the same floor/offset/wrap and the same seeded
``lowbias32`` hash as :mod:`behaviours.tile_coding`, all intermediates < 2**49 in int64), and
followed by ``argmax``. It takes the raw normalised inputs, so a robot needs nothing but torch.

The file format is ``torch.export`` (``.pt2``): TorchScript is deprecated as of torch 2.13 (its
``script``/``save``/``load`` warn), and an exported program can be loaded from Python
(:func:`load_exported_policy`) or compiled ahead of time for C++ (AOTInductor). The batch
dimension is dynamic. The values' header (coder, action names, checksum, metadata) travels with
the program as the extra file ``action_values.json``.

The module checks its input in the graph: any value outside [0, 1] or NaN raises a
``RuntimeError`` naming the allowed range (torch cannot raise ``ValueError`` from a graph). Input
must be float64 of shape (batch, n_dims); the exported graph asserts the dtype.

torch is an optional dependency (``pip install cyber-rodent[export]``); only this module imports
it, and importing the rest of :mod:`behaviours` never does.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
from typing import Any

try:
    import torch
    from torch import nn
except ImportError as err:  # pragma: no cover - depends on the installation
    raise ImportError(
        "behaviours.export needs torch: pip install 'cyber-rodent[export]' (torch==2.13.0)"
    ) from err

from behaviours.action_values import ActionValues
from behaviours.greedy_policy import GreedyPolicy
from behaviours.tile_coding import MASK16, MASK32, MIX_MUL_1, MIX_MUL_2, TileCoder
from cyber_rodent.atomic import atomic_output

#: Name of the JSON description stored next to the program in the ``.pt2`` archive.
METADATA_FILE = "action_values.json"


def _mul32(x: torch.Tensor, constant: int) -> torch.Tensor:
    lo = constant & MASK16
    hi = constant >> 16
    return (x * lo + (((x * hi) & MASK16) << 16)) & MASK32


def _mix32(x: torch.Tensor) -> torch.Tensor:
    x = x ^ (x >> 16)
    x = _mul32(x, MIX_MUL_1)
    x = x ^ (x >> 15)
    x = _mul32(x, MIX_MUL_2)
    return x ^ (x >> 16)


class TileCodedGreedyPolicy(nn.Module):
    """Greedy policy of tile-coded linear Q values as a torch module.

    ``forward(states)`` maps float64 (batch, n_dims) inputs in [0, 1] to int64 (batch,) greedy
    actions (ties to the lowest index, like :class:`~behaviours.greedy_policy.GreedyPolicy`).

    Args:
        values: the learned action values to embed.
    """

    # Registered buffers (typed here: ``nn.Module.__getattr__`` says Tensor | Module).
    scale: torch.Tensor
    offsets: torch.Tensor
    coordinate_count: torch.Tensor
    tiling_hash: torch.Tensor

    def __init__(self, values: ActionValues) -> None:
        super().__init__()
        coder = TileCoder(values.coder_config)
        self.n_dims = values.coder_config.n_dims
        self.n_tilings = values.coder_config.n_tilings
        self.table_size = values.coder_config.table_size
        self.register_buffer("scale", torch.from_numpy(coder.scale.copy()))
        self.register_buffer("offsets", torch.from_numpy(coder.offsets.copy()))
        self.register_buffer("coordinate_count", torch.from_numpy(coder.coordinate_count.copy()))
        self.register_buffer("tiling_hash", torch.from_numpy(coder.tiling_hash.copy()))
        self.q_table = nn.EmbeddingBag.from_pretrained(
            torch.from_numpy(values.weights.T.copy()), freeze=True, mode="sum"
        )

    def tile_indices(self, states: torch.Tensor) -> torch.Tensor:
        """Hashed tile indices (batch, n_tilings), equal to :meth:`TileCoder.indices`."""
        q = torch.floor(states * self.scale).to(torch.int64)
        coords = torch.div(q.unsqueeze(1) + self.offsets, self.n_tilings, rounding_mode="floor")
        coords = torch.remainder(coords, self.coordinate_count)
        h = self.tiling_hash.expand(coords.shape[0], self.n_tilings)
        for d in range(self.n_dims):
            h = _mix32(h ^ coords[:, :, d])
        return torch.remainder(h, self.table_size)

    def q_values(self, states: torch.Tensor) -> torch.Tensor:
        """Action values (batch, n_actions) float64."""
        torch._assert_async(
            ((states >= 0.0) & (states <= 1.0)).all(),
            "states: every input must be a normalised value in [0, 1] (no NaN)",
        )
        q: torch.Tensor = self.q_table(self.tile_indices(states))  # Module.__call__ is untyped
        return q

    def forward(self, states: torch.Tensor) -> torch.Tensor:
        """Greedy actions (batch,) int64."""
        return torch.argmax(self.q_values(states), dim=1)


def _as_values(policy: GreedyPolicy | ActionValues) -> ActionValues:
    if isinstance(policy, GreedyPolicy):
        return policy.values
    if isinstance(policy, ActionValues):
        return policy
    raise ValueError(f"policy: need a GreedyPolicy or ActionValues, got {type(policy).__name__}")


def export_greedy_policy(policy: GreedyPolicy | ActionValues, path: str | os.PathLike[str]) -> Path:
    """Export the greedy policy with ``torch.export`` to a ``.pt2`` file.

    Args:
        policy: the greedy policy (or its action values).
        path: destination; must end in ``.pt2``.

    Returns:
        The written path.
    """
    values = _as_values(policy)
    path = Path(path)
    if path.suffix != ".pt2":
        raise ValueError(f"path: exported policies are saved as .pt2, got {str(path)!r}")
    module = TileCodedGreedyPolicy(values).eval()
    example = torch.full((2, values.coder_config.n_dims), 0.5, dtype=torch.float64)
    batch = torch.export.Dim("batch", min=1, max=1 << 20)
    program = torch.export.export(module, (example,), dynamic_shapes={"states": {0: batch}})
    description = {
        "coder": values.coder_config.to_dict(),
        "action_names": list(values.action_names),
        "n_actions": values.n_actions,
        "values_sha256": values.checksum,
        "metadata": values.metadata,
        "input": f"float64 (batch, {values.coder_config.n_dims}) in [0, 1]",
        "output": "int64 (batch,) greedy action index",
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(path) as temp:
        torch.export.save(program, temp, extra_files={METADATA_FILE: json.dumps(description)})
    return path


def load_exported_policy(path: str | os.PathLike[str]) -> tuple[nn.Module, dict[str, Any]]:
    """Load a policy written by :func:`export_greedy_policy`.

    Returns:
        ``(module, description)``: the callable module (float64 (batch, n_dims) → int64 actions)
        and the JSON description stored with it (coder, action names, values checksum).

    Raises:
        FileNotFoundError: no file at ``path``.
        ValueError: the file is not a readable exported policy.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"exported policy not found: {path}")
    extra = {METADATA_FILE: ""}
    try:
        program = torch.export.load(path, extra_files=extra)
        description = json.loads(extra[METADATA_FILE])
    except Exception as err:  # torch raises many types for a damaged archive
        raise ValueError(f"{path}: not a readable exported policy ({err})") from err
    return program.module(), description


def export_behaviour_policies(
    out_dir: str | os.PathLike[str], values_dir: str | os.PathLike[str] | None = None
) -> dict[str, Path]:
    """Export the greedy policy of every behaviour's trained values as ``<name>.pt2``.

    Every values file is read before anything is written, and each program is written
    atomically, so a missing or damaged file leaves ``out_dir`` as it was.

    Args:
        out_dir: destination directory (created if needed).
        values_dir: where ``{mate,forage,search}.npz`` live; default the shipped values.

    Returns:
        ``{behaviour name: written path}``.

    Raises:
        FileNotFoundError, ActionValuesError: a values file is missing, damaged or incompatible.
    """
    from behaviours.definitions import load_values
    from behaviours.inputs import BEHAVIOUR_NAMES

    values = {name: load_values(name, values_dir) for name in BEHAVIOUR_NAMES}
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return {name: export_greedy_policy(v, out / f"{name}.pt2") for name, v in values.items()}


#: Exit status of every user error.
EXIT_USAGE = 2


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``export`` command's options to ``parser``."""
    parser.add_argument("--out", required=True, metavar="DIR",
                        help="output directory (created if needed)")  # fmt: skip
    parser.add_argument(
        "--values", default=None, metavar="DIR",
        help="directory of mate.npz, forage.npz and search.npz (default: the shipped values)",
    )  # fmt: skip
    parser.set_defaults(export_prog=parser.prog)


def run(args: argparse.Namespace) -> int:
    """Export the three behaviours; 0 on success, 2 (one line on stderr) on bad input.

    ``--out`` and ``--values`` are checked, and every values file read, before anything is
    written.
    """
    import sys

    prog = getattr(args, "export_prog", "behaviours.export")
    try:
        out = Path(args.out).expanduser()
        if out.exists() and not out.is_dir():
            raise ValueError(f"--out {out} is a file; it must be a directory (new or existing)")
        if args.values is not None and not Path(args.values).is_dir():
            raise ValueError(
                f"--values {args.values} is not a directory; it must hold mate.npz, forage.npz "
                "and search.npz"
            )
        paths = export_behaviour_policies(out, args.values)
    except (OSError, ValueError) as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        return EXIT_USAGE
    for name, path in paths.items():
        print(f"{name}: wrote {path}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m behaviours.export --out DIR``: export the three shipped behaviours."""
    parser = argparse.ArgumentParser(
        prog="python -m behaviours.export",
        description="Export the greedy Mate, Forage and Search policies as torch.export .pt2 "
        "programs for robot controllers (input: float64 (batch, 2) in [0, 1]; output: wheel "
        "command index). Load one with torch.export.load(path).module().",
    )
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
