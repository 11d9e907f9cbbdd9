"""Pictures: panel and line counts, replaced parts, atomic saving."""

from __future__ import annotations

import os

import numpy as np
import pytest
from matplotlib.collections import LineCollection
from PIL import Image

from shapetree import ShapeTreeError
from shapetree.demo import demo_shape
from shapetree.matching import match
from shapetree.plotting import (
    merge_replaced,
    new_figure,
    plot_deformations,
    plot_match,
    plot_ranking,
    plot_tree,
    save_figure,
)
from shapetree.tree import build_shape_tree


@pytest.fixture(scope="module")
def g_match():
    g = demo_shape("glyph-G", n_points=40)
    s = demo_shape("glyph-S", n_points=40)
    return match(g, s)


def _line_collections(ax):
    return [c for c in ax.collections if isinstance(c, LineCollection)]


def test_plot_match_draws_subsampled_correspondences(g_match):
    fig = plot_match(g_match, max_lines=12)
    assert len(fig.axes) == 1
    ax = fig.axes[0]
    (lc,) = _line_collections(ax)
    assert len(lc.get_segments()) == 12
    assert f"{g_match.cost:.4g}" in ax.get_title()
    fig = plot_match(g_match, max_lines=1000)
    (lc,) = _line_collections(fig.axes[0])
    assert len(lc.get_segments()) == np.isfinite(g_match.a_to_b).sum()


def test_plot_match_labels_replaced_parts():
    res = match(demo_shape("hand", n_points=48), demo_shape("hand-cut", n_points=48), occlusion=1.0)
    assert res.replaced
    fig = plot_match(res)
    ax = fig.axes[0]
    texts = [t.get_text() for t in ax.texts]
    n_parts = len(merge_replaced(res.replaced, 48, 48, True))
    assert "R1" in texts and texts.count("R1") == 2  # labelled on both shapes
    assert sum(t.startswith("R") and t[1:].isdigit() for t in texts) == 2 * n_parts
    assert "replaced" in ax.get_title()
    assert ax.get_legend() is not None


def test_plot_match_into_given_axes_and_path(g_match, tmp_path):
    fig = new_figure(4, 3)
    ax = fig.add_subplot()
    assert plot_match(g_match, ax) is fig
    out = tmp_path / "m.png"
    plot_match(g_match, out)  # a path in place of the axes
    with Image.open(out) as im:
        assert im.format == "PNG" and im.width > 300


def test_merge_replaced_joins_runs():
    parts = [(0, 3, 10, 12), (3, 6, 12, 15), (8, 9, 20, 21), (18, 0, 5, 10)]
    assert merge_replaced(parts, 20, 30, True) == [(18, 6, 5, 15), (8, 9, 20, 21)]
    assert merge_replaced(parts[:3], 20, 30, False) == [(0, 6, 10, 15), (8, 9, 20, 21)]


def test_plot_tree_has_one_panel_per_depth():
    tree = build_shape_tree(demo_shape("star", n_points=32), closed=True)
    fig = plot_tree(tree)
    assert len(fig.axes) == tree.max_depth + 1
    for d, ax in enumerate(fig.axes):
        assert ax.get_title().startswith(f"depth {d}:")
    assert len(plot_tree(tree, max_levels=2).axes) == 2
    with pytest.raises(ShapeTreeError):
        plot_tree(tree, max_levels=0)


def test_plot_tree_open_curve():
    t = np.linspace(0, np.pi, 17)
    tree = build_shape_tree(np.c_[np.cos(t), np.sin(t)], closed=False)
    assert len(plot_tree(tree).axes) == tree.max_depth + 1


def test_plot_deformations_grid():
    tree = build_shape_tree(demo_shape("square", n_points=32), closed=True)
    fig = plot_deformations(tree, [0.02, 0.05], n=3, rng=0)
    assert len(fig.axes) == 2 * 4
    assert fig.axes[0].get_ylabel() == "σ = 0.02"
    fig = plot_deformations([tree, tree], 0.03, n=2, rng=1)
    assert len(fig.axes) == 2 * 3
    per_depth = np.full(tree.max_depth + 1, 0.01)
    assert len(plot_deformations(tree, per_depth, n=1, rng=0).axes) == 2


def test_plot_ranking_panels():
    q = demo_shape("leaf", n_points=24)
    cands = [("a", q, 0.1, True), ("b", demo_shape("star", n_points=24), 0.5)]
    fig = plot_ranking(q, cands)
    assert len(fig.axes) == 3
    assert fig.axes[1].get_title().startswith("#1 a")


def test_save_figure_is_atomic(tmp_path):
    fig = new_figure(2, 2)
    fig.add_subplot().plot([0, 1], [0, 1])
    out = tmp_path / "sub" / "fig.png"
    assert save_figure(fig, out) == out
    assert os.listdir(out.parent) == ["fig.png"]
    with Image.open(out) as im:
        im.verify()
    before = out.read_bytes()

    def boom(*args, **kwargs):
        raise RuntimeError("disk on fire")

    fig.savefig = boom  # a failure half-way through writing
    with pytest.raises(RuntimeError):
        save_figure(fig, out)
    assert os.listdir(out.parent) == ["fig.png"]  # no temp file left
    assert out.read_bytes() == before  # old picture untouched


def test_save_figure_rejects_unknown_format(tmp_path):
    fig = new_figure(2, 2)
    with pytest.raises(ShapeTreeError, match="unsupported picture format"):
        save_figure(fig, tmp_path / "fig.xyz")
    with pytest.raises(ShapeTreeError, match="is a directory"):
        save_figure(fig, _dir_png(tmp_path))
    assert not list(tmp_path.glob(".*"))


def _dir_png(tmp_path):
    d = tmp_path / "dir.png"
    d.mkdir()
    return d


def test_saved_pictures_get_ordinary_permissions(tmp_path):
    fig = new_figure(1, 1)
    out = save_figure(fig, tmp_path / "p.png")
    mask = os.umask(0)
    os.umask(mask)
    assert out.stat().st_mode & 0o777 == 0o666 & ~mask
