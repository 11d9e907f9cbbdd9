"""The README's Python example runs as written, and its quick start matches .ci/run."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from shapetree.curves import resample
from shapetree.matching import match, match_cost, prepare_target

REPO = Path(__file__).resolve().parents[1]


def _run_readme_example() -> dict:
    text = (REPO / "README.md").read_text()
    block = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    ns: dict = {}
    exec(compile(block, "README.md", "exec"), ns)
    return ns


def _similar_copy(a: np.ndarray, start: int = 37) -> np.ndarray:
    """``a`` rotated, scaled, shifted and started at point ``start`` (the same shape)."""
    th = 0.7
    rot = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    return np.roll(2.5 * a @ rot.T + [3.0, -1.0], -start, axis=0)


def test_readme_python_example_runs():
    ns = _run_readme_example()
    a, b, res, others, D = ns["a"], ns["b"], ns["res"], ns["others"], ns["D"]
    # a shape matches its rotated, scaled, shifted, re-started copy at almost no cost, far
    # below its cost against the other shape (the matching is similarity-invariant)
    cost_ab = match(a, b, n_points=50).cost
    assert cost_ab > 1e-4
    assert 0 <= match(a, _similar_copy(a), n_points=50).cost < 0.02 * cost_ab
    # the occlusion run: a correspondence into B's samples and well-formed replaced parts
    assert np.isfinite(res.cost) and res.cost >= 0
    pos, n_a = res.a_to_b, len(res.a)
    assert pos.shape == (n_a,) == (50,)
    assert match(a, ns["c"]).cost < 0.02 * match(a, b).cost
    ok = np.isfinite(pos)
    assert ok.sum() >= n_a // 2 and np.all((pos[ok] >= 0) & (pos[ok] < len(res.b)))
    assert all(len(r) == 4 for r in res.replaced)
    for i in np.flatnonzero(~ok):  # no correspondence only strictly inside a replaced part
        assert any(0 < (i - s) % n_a < (e - s) % n_a for s, e, _, _ in res.replaced)
    # the shape-tree and a deformed copy of its curve
    tree, noisy = ns["tree"], ns["noisy"]
    assert tree.coords.shape == (len(tree.points) - 2, 2)
    assert noisy.shape == tree.points.shape and not np.allclose(noisy, tree.points)
    # one model, many targets: a similar copy costs nothing, the deformed copies something
    costs = np.asarray(ns["costs"])
    assert costs.shape == (5,) and np.all(np.isfinite(costs))
    copy = resample(_similar_copy(a, start=0), 50, closed=True)  # samples where the model has them
    assert match_cost(ns["model"], prepare_target(copy)) < 1e-9
    assert np.all(costs > 1e-4)
    # the distance matrix: one row and column per curve, zero diagonal, positive elsewhere
    n = 2 + len(others)
    assert D.shape == (n, n) and np.all(np.isfinite(D))
    assert np.all(np.abs(np.diag(D)) < 1e-9)
    assert np.all(D[~np.eye(n, dtype=bool)] > 1e-4)
    assert ns["R"].shape == (n, n) and np.all(np.isfinite(ns["R"]))


def test_readme_deformed_copies_rank_closer_than_the_other_shape():
    ns = _run_readme_example()
    b, D = ns["b"], ns["D"]
    costs = np.asarray(ns["costs"])
    cost_b = match_cost(ns["model"], prepare_target(resample(b, 50, closed=True)))
    assert costs.max() < 0.5 * cost_b  # every deformed copy of A beats B, by a margin
    assert np.all(D[0, 2:] < 0.5 * D[0, 1])  # A's row: the copies before B
    assert np.all(D[2:, 0] < 0.5 * D[2:, 1])  # each copy is closer to A than to B


def test_readme_test_command_is_what_ci_runs():
    text = (REPO / "README.md").read_text()
    quick = re.search(r"```bash\n(.*?)```", text, re.S).group(1).strip().splitlines()
    assert len(quick) == 2, "the README opens with exactly two set-up commands"
    assert "shapetree demo" in quick[0]
    test_cmd = quick[1].split("#")[0].strip()
    assert test_cmd in (REPO / ".ci" / "run").read_text()
