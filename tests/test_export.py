"""Torch export of the greedy policy: same indices, same values, same actions as numpy."""

from __future__ import annotations

import argparse
import re
import subprocess
import sys

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from behaviours.action_values import ActionValues  # noqa: E402
from behaviours.export import (  # noqa: E402
    TileCodedGreedyPolicy,
    add_arguments,
    export_greedy_policy,
    load_exported_policy,
    main,
    run,
)
from behaviours.greedy_policy import GreedyPolicy  # noqa: E402
from behaviours.tile_coding import TileCoderConfig  # noqa: E402

CODER = TileCoderConfig(
    resolution=(12, 6, 5), n_tilings=8, table_size=1000, wrap=(True, False, False), seed=7
)


def _values(seed: int = 1) -> ActionValues:
    """Random weights with most columns exactly zero, as after training (unvisited tiles), so
    many states have exactly tied actions and the tie rule is exercised too."""
    rng = np.random.default_rng(seed)
    weights = rng.normal(size=(5, CODER.table_size))
    weights[:, rng.random(CODER.table_size) < 0.7] = 0.0
    return ActionValues(CODER, weights, ("fwd", "left", "right", "back", "stop"))


def _inputs(n: int, seed: int = 2) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x = rng.random((n, 3))
    # Exact tile edges and the ends of the range, where floor/wrap could disagree.
    edges = np.array([[k / 96, k / 48, k / 40] for k in range(0, 41)])
    return np.concatenate([x, edges, np.zeros((1, 3)), np.ones((1, 3))])


@pytest.fixture(scope="module")
def values() -> ActionValues:
    return _values()


def test_module_matches_numpy_indices_values_and_actions(values):
    policy = GreedyPolicy(values)
    module = TileCodedGreedyPolicy(values)
    x = _inputs(20_000)
    xt = torch.from_numpy(x)
    assert np.array_equal(module.tile_indices(xt).numpy(), policy.coder.indices(x))
    assert np.array_equal(module.q_values(xt).numpy(), policy.q_values(x))  # bit-identical
    actions = policy.act(x)
    assert np.array_equal(module(xt).numpy(), actions)
    assert len(set(actions.tolist())) == 5  # every action occurs: not a degenerate comparison


def test_exported_file_round_trip(values, tmp_path):
    path = export_greedy_policy(GreedyPolicy(values), tmp_path / "forage.pt2")
    module, description = load_exported_policy(path)
    x = _inputs(5000, seed=3)
    assert np.array_equal(module(torch.from_numpy(x)).numpy(), GreedyPolicy(values).act(x))
    assert module(torch.from_numpy(x[:1])).shape == (1,)  # dynamic batch size
    assert description["action_names"] == list(values.action_names)
    assert description["values_sha256"] == values.checksum
    assert TileCoderConfig.from_dict(description["coder"]) == CODER


def test_all_zero_values_choose_action_zero_in_both(tmp_path):
    values = ActionValues(CODER, np.zeros((5, CODER.table_size)))
    x = _inputs(200)
    assert not GreedyPolicy(values).act(x).any()
    assert not TileCodedGreedyPolicy(values)(torch.from_numpy(x)).any()


@pytest.mark.parametrize("bad", [1.5, -0.1, float("nan")])
def test_out_of_range_input_is_rejected_by_the_module(values, bad):
    x = torch.full((2, 3), 0.5, dtype=torch.float64)
    x[1, 2] = bad
    with pytest.raises(RuntimeError, match=r"\[0, 1\]"):
        TileCodedGreedyPolicy(values)(x)


def test_bad_paths_are_clear_errors(values, tmp_path):
    with pytest.raises(ValueError, match="path"):
        export_greedy_policy(values, tmp_path / "policy.pt")
    with pytest.raises(ValueError, match="policy"):
        export_greedy_policy("forage", tmp_path / "policy.pt2")
    with pytest.raises(FileNotFoundError, match="exported policy not found"):
        load_exported_policy(tmp_path / "missing.pt2")
    broken = tmp_path / "broken.pt2"
    broken.write_bytes(b"not a torch archive")
    with pytest.raises(ValueError, match="not a readable exported policy"):
        load_exported_policy(broken)


def test_core_does_not_import_torch():
    script = (
        "import sys\n"
        "import behaviours.tile_coding, behaviours.sarsa, behaviours.action_values\n"
        "import behaviours.greedy_policy\n"
        "print('torch' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_command_exports_through_the_mountable_pair(tmp_path, capsys):
    from behaviours.definitions import load_values

    parser = argparse.ArgumentParser(prog="cyber-rodent export")
    add_arguments(parser)
    assert run(parser.parse_args(["--out", str(tmp_path / "out")])) == 0
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "forage.pt2", "mate.pt2", "search.pt2"
    ]  # no temporaries left
    x = np.random.default_rng(6).random((500, 2))
    module = torch.export.load(tmp_path / "out" / "mate.pt2").module()  # the documented call
    assert np.array_equal(module(torch.from_numpy(x)).numpy(),
                          GreedyPolicy(load_values("mate")).act(x))  # fmt: skip
    assert "mate: wrote" in capsys.readouterr().out


def test_command_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys):
    from behaviours.definitions import values_path

    (tmp_path / "file").write_text("mine")
    partial = tmp_path / "partial"
    partial.mkdir()
    (partial / "mate.npz").write_bytes(values_path("mate").read_bytes())  # forage is missing
    cases = [
        (["--out", str(tmp_path / "file")], "--out .*file is a file"),
        (["--out", str(tmp_path / "new"), "--values", str(tmp_path / "none")],
         "--values .*none is not a directory; it must hold mate.npz, forage.npz and search.npz"),
        (["--out", str(tmp_path / "new"), "--values", str(partial)], "forage"),
    ]  # fmt: skip
    for argv, message in cases:
        before = sorted(tmp_path.rglob("*"))
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("python -m behaviours.export: error: ")
        assert re.search(message, err), err
        assert sorted(tmp_path.rglob("*")) == before
