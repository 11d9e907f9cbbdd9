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
from shapetree.plotting import plot_deformations, plot_match, plot_ranking, plot_tree, save_figure
from shapetree.plotting._draw import merge_replaced
from shapetree.plotting._save import new_figure
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


# ------------------------------------------------------------------ retrieval pictures


def _retrieval_set():
    """Two classes of three shapes; shape 2 ("star" class) sits nearer the squares."""
    curves = [demo_shape(n, n_points=24) for n in ("square", "square", "star")]
    curves += [demo_shape("star", n_points=24)] * 3
    labels = np.array(["sq", "sq", "sq", "st", "st", "st"])
    D = np.abs(np.arange(6)[:, None] - np.arange(6)[None, :]).astype(float)
    return D, labels, curves


def test_plot_retrieval_grid_panels_and_wrong_matches(tmp_path):
    import matplotlib.pyplot as plt

    from shapetree.plotting import plot_retrieval_grid

    D, labels, curves = _retrieval_set()
    fig = plot_retrieval_grid(D, labels, curves, n_top=3, title="t")
    assert len(fig.axes) == 2 * 4  # one query per class, query + 3 neighbours
    red = [ax for ax in fig.axes if ax.spines["left"].get_edgecolor()[:3] == (1.0, 0.0, 0.0)]
    assert red  # the nearest shapes of another class are framed in red
    assert fig.axes[0].get_title() == "query"
    out = tmp_path / "grid.png"
    assert plot_retrieval_grid(D, labels, curves, n_top=2, queries=[0], path=out) is not None
    with Image.open(out) as im:
        assert im.format == "PNG"
    assert len(plot_retrieval_grid(D, labels, curves, n_top=99).axes) == 2 * 6  # n_top capped
    assert plt.get_fignums() == []  # never registered with pyplot


def test_plot_bullseye_per_class_bars(tmp_path):
    from shapetree.plotting import plot_bullseye_per_class

    per_class = {"a": 95.0, "b": 60.0, "c": 80.0}
    fig = plot_bullseye_per_class(per_class, overall=78.3, second={"a": 99, "b": 70, "c": 90})
    (ax,) = fig.axes
    assert len(ax.patches) == 3
    assert [t.get_text() for t in ax.get_yticklabels()] == ["b", "c", "a"]  # worst first
    assert ax.get_legend() is not None
    out = plot_bullseye_per_class(per_class, path=tmp_path / "b.svg")
    assert (tmp_path / "b.svg").read_text().lstrip().startswith("<?xml") and out is not None


def test_file_forms_return_the_path_and_check_it_first(tmp_path):
    from shapetree.plotting._retrieval import (
        save_bullseye_per_class,
        save_retrieval_grid,
        save_search,
    )

    D, labels, curves = _retrieval_set()
    out = save_retrieval_grid(D, labels, curves, tmp_path / "g.png", n_top=2)
    assert out == tmp_path / "g.png" and out.stat().st_size > 1000
    out = save_bullseye_per_class({"a": 50.0}, tmp_path / "sub" / "b.png", overall=50.0)
    assert out == tmp_path / "sub" / "b.png" and out.is_file()
    out = save_search(curves[0], curves[1:4], ["a\n0.1", "b\n0.2", "c\n0.3"], tmp_path / "s.png")
    assert out == tmp_path / "s.png" and out.is_file()
    with pytest.raises(ShapeTreeError, match="unsupported picture format"):
        save_search(curves[0], curves[1:2], ["a"], tmp_path / "s.xyz")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.png", "s.png", "sub"]


# ------------------------------------------------------------------ detection pictures


def _circle(n: int = 60, r: float = 30.0, c=(50.0, 50.0)) -> np.ndarray:
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.c_[c[0] + r * np.cos(t), c[1] + r * np.sin(t)]


def test_plot_contours_one_line_per_contour():
    from shapetree.plotting import plot_contours

    contours = [_circle()[:25], _circle()[30:55]]
    ax = plot_contours(contours, (100, 120))
    lines = ax.get_lines()
    assert len(lines) == 4  # each contour and its two endpoints
    assert ax.get_xlim() == (0.0, 120.0) and ax.get_ylim() == (100.0, 0.0)  # y down
    assert len(plot_contours(contours, endpoints=False).get_lines()) == 2


def test_plot_detections_fig5_panels(tmp_path):
    import matplotlib.pyplot as plt

    from shapetree.detection import detect_detailed
    from shapetree.plotting import plot_detections

    circle = _circle()
    run = detect_detailed(circle, None, contours=[circle[:25], circle[30:55]], k=2)
    assert run.detections
    fig = plot_detections(run, np.ones((100, 100, 3)) * 0.5, n_show=2, title="circle")
    assert len(fig.axes) == 4
    assert [ax.get_title()[:3] for ax in fig.axes] == ["(a)", "(b)", "(c)", "(d)"]
    legend = fig.axes[3].get_legend()
    assert legend is not None and len(legend.get_texts()) == min(2, len(run.detections))
    out = tmp_path / "det.png"
    plot_detections(run, path=out)  # no image: the detections go over the edges (if any)
    with Image.open(out) as im:
        assert im.format == "PNG"
    assert plt.get_fignums() == []


def test_detect_to_files_picture_format_follows_the_extension(tmp_path):
    """The picture is drawn by plotting and saved by save_figure (format from the name);
    a bad picture name fails before any detection work."""
    from shapetree.detection import detect_to_files

    img = np.full((90, 90), 255, np.uint8)
    yy, xx = np.mgrid[:90, :90]
    img[(yy - 45) ** 2 + (xx - 45) ** 2 < 30**2] = 0  # a dark disc
    Image.fromarray(img).save(tmp_path / "scene.png")
    np.save(tmp_path / "model.npy", _circle(40, 10.0, (0.0, 0.0)))
    out = tmp_path / "det.svg"
    dets = detect_to_files(tmp_path / "model.npy", tmp_path / "scene.png", out_png=out, k=1)
    assert isinstance(dets, list)
    assert out.read_text().lstrip().startswith("<?xml")
    with pytest.raises(ShapeTreeError, match="unsupported picture format"):
        detect_to_files(tmp_path / "model.npy", tmp_path / "missing.png", out_png=tmp_path / "x.q")


def test_refined_box_is_drawn_beside_the_match_box():
    """A refined detection draws its reported box dashed and the match's box dotted."""
    import dataclasses

    import matplotlib.pyplot as plt

    from shapetree.detection import detect_detailed
    from shapetree.plotting._detection import _draw_detection

    circle = _circle()
    run = detect_detailed(circle, None, contours=[circle[:25], circle[30:55]], k=1)
    det = run.detections[0]
    grown = tuple(v * f for v, f in zip(det.bbox, (0.5, 0.5, 1.5, 1.5), strict=True))
    refined = dataclasses.replace(det, bbox=grown, match_bbox=det.bbox)
    for d, n_boxes in ((det, 1), (refined, 2)):
        fig, ax = plt.subplots()
        _draw_detection(d, run.contours, ax)
        boxes = [ln for ln in ax.get_lines() if len(ln.get_xdata()) == 5]
        assert len(boxes) == n_boxes
        assert boxes[-1].get_linestyle() == "--"
        assert (min(boxes[-1].get_xdata()), max(boxes[-1].get_ydata())) == pytest.approx(
            (d.bbox[0], d.bbox[3])
        )
        plt.close(fig)
