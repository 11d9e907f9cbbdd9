"""OpenCV contours and shapely polygons through plotting and detection.

Every public function of ``shapetree.plotting`` and ``shapetree.detection`` that takes a curve
reads it like :func:`shapetree.curves.as_curve`: a real ``cv2.findContours`` contour (``(n, 1,
2)`` int32) and a shapely ``Polygon`` / ``LinearRing`` (its exterior) give the same figure data,
model points and detections as the plain ``(n, 2)`` float array, and a bad shape is a
``ShapeTreeError`` naming the accepted forms. Image contours (``contours=`` of ``detect``, and
``plot_contours``) are open polylines through the points, first to last: a ring's repeated
closing point is dropped, as OpenCV gives closed boundaries.
"""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.collections import PathCollection
from matplotlib.patches import Polygon as PolygonPatch

from shapetree import CurveError, ShapeTreeError
from shapetree.detection import (
    DetectParams,
    detect,
    detect_detailed,
    load_model,
    make_model,
)
from shapetree.plotting import (
    plot_contours,
    plot_curve,
    plot_deformations,
    plot_detections,
    plot_ranking,
    plot_retrieval_grid,
    plot_tree,
)
from shapetree.tree import build_shape_tree

cv2 = pytest.importorskip("cv2")
geometry = pytest.importorskip("shapely.geometry")

ACCEPTED = ["(n, 2)", "(n, 1, 2)", "LineString", "LinearRing", "Polygon", "__geo_interface__"]


def _outline(t: np.ndarray, scale: float, centre: tuple[float, float]) -> np.ndarray:
    r = scale * (1 + 0.3 * np.cos(3 * t) + 0.15 * np.sin(2 * t))  # no symmetry
    return np.c_[centre[0] + r * np.cos(t), centre[1] + r * np.sin(t)]


def _find_contours(shape: tuple[int, int], *polys: np.ndarray, approx: int) -> list[np.ndarray]:
    """Fill ``polys`` into a uint8 image and trace them back with ``cv2.findContours``."""
    img = np.zeros(shape, np.uint8)
    for p in polys:
        cv2.fillPoly(img, [np.round(p).astype(np.int32)], 255)
    contours, _ = cv2.findContours(img, cv2.RETR_EXTERNAL, approx)
    return sorted(contours, key=lambda c: -len(c))


@pytest.fixture(scope="module")
def blob() -> np.ndarray:
    """One real OpenCV contour of a filled blob: (n, 1, 2) int32, a few dozen points."""
    t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    (c,) = _find_contours((80, 90), _outline(t, 22.0, (45.0, 40.0)), approx=cv2.CHAIN_APPROX_SIMPLE)
    assert c.ndim == 3 and c.shape[1:] == (1, 2) and c.dtype == np.int32 and len(c) >= 20
    return c


def _plain(c: np.ndarray) -> np.ndarray:
    return c.reshape(-1, 2).astype(np.float64)


def _forms(c: np.ndarray) -> dict[str, object]:
    """The OpenCV contour and the shapely forms of the same closed curve."""
    p = _plain(c)
    return {
        "opencv": c,
        "Polygon": geometry.Polygon(p),
        "LinearRing": geometry.LinearRing(p),
    }


def _figure_data(fig) -> list[np.ndarray]:
    """Everything drawn: line vertices, filled patches, scatter offsets, texts."""
    out: list[np.ndarray] = []
    for ax in fig.axes:
        out += [np.asarray(line.get_xydata(), dtype=float) for line in ax.get_lines()]
        out += [
            np.asarray(p.get_xy(), dtype=float) for p in ax.patches if isinstance(p, PolygonPatch)
        ]
        out += [
            np.asarray(c.get_offsets()) for c in ax.collections if isinstance(c, PathCollection)
        ]
        out.append(np.array([ax.get_title(), ax.get_xlim(), ax.get_ylim()], dtype=object))
    return out


def _same_figure(a, b) -> None:
    da, db = _figure_data(a), _figure_data(b)
    assert len(da) == len(db) > 0
    for x, y in zip(da, db, strict=True):
        if x.dtype == object:
            assert x.tolist() == y.tolist()
        else:
            np.testing.assert_array_equal(x, y)


def _names_the_forms(info: pytest.ExceptionInfo, *also: str) -> None:
    msg = str(info.value)
    for word in [*ACCEPTED, *also]:
        assert word in msg, (word, msg)


BAD = np.zeros((6, 3))  # three columns: not a curve in any accepted form


# ---------------------------------------------------------------- plotting


def test_plot_curve(blob) -> None:
    plain = plot_curve(_plain(blob)).figure
    for form in _forms(blob).values():
        _same_figure(plot_curve(form).figure, plain)
    with pytest.raises(CurveError) as info:
        plot_curve(BAD)
    _names_the_forms(info, "plot_curve")
    with pytest.raises(CurveError, match="closed curve"):
        plot_curve(geometry.Polygon(_plain(blob)), closed=False)


def test_plot_ranking(blob) -> None:
    p = _plain(blob)
    other = p * np.array([1.0, 0.6])
    cands = lambda q, o: [("same", q, 0.0, True), ("squashed", o, 0.4)]  # noqa: E731
    plain = plot_ranking(p, cands(p, other))
    for form in _forms(blob).values():
        squashed = geometry.Polygon(other) if form is not blob else other
        _same_figure(plot_ranking(form, cands(form, squashed)), plain)
    with pytest.raises(CurveError) as info:
        plot_ranking(p, [("bad", BAD, 0.1)])
    _names_the_forms(info, "candidate #1 (bad)")
    with pytest.raises(CurveError) as info:
        plot_ranking(BAD, [])
    _names_the_forms(info, "query")
    with pytest.raises(ShapeTreeError, match="candidate #1 must be a"):
        plot_ranking(p, [p])


def test_plot_retrieval_grid(blob) -> None:
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    second = _find_contours(
        (80, 90), _outline(t, 15.0, (40.0, 45.0)), approx=cv2.CHAIN_APPROX_SIMPLE
    )[0]
    square = np.array([[10, 10], [60, 10], [60, 50], [10, 50]], np.int32)[:, None, :]
    cv = [blob, second, square]
    D = np.array([[0.0, 0.1, 0.9], [0.1, 0.0, 0.8], [0.9, 0.8, 0.0]])
    labels = ["blob", "blob", "square"]
    plain = plot_retrieval_grid(D, labels, [_plain(c) for c in cv], n_top=2)
    _same_figure(plot_retrieval_grid(D, labels, cv, n_top=2), plain)
    polygons = [geometry.Polygon(_plain(c)) for c in cv]
    _same_figure(plot_retrieval_grid(D, labels, polygons, n_top=2), plain)
    with pytest.raises(CurveError) as info:
        plot_retrieval_grid(D, labels, [blob, BAD, square], n_top=2)
    _names_the_forms(info, "curves[1]")


def test_plot_contours(blob) -> None:
    p = _plain(blob)
    pieces = [blob[:15], blob[15:]]  # slices of a real contour stay (k, 1, 2) int32
    plain = plot_contours([_plain(c) for c in pieces], (80, 90)).figure
    _same_figure(plot_contours(pieces, (80, 90)).figure, plain)
    # a ring is drawn as detection reads it: its points first to last, like OpenCV's contour
    whole = plot_contours([p], (80, 90)).figure
    for form in (blob, geometry.Polygon(p), geometry.LinearRing(p)):
        _same_figure(plot_contours([form], (80, 90)).figure, whole)
    line = geometry.LineString(p[:20])
    _same_figure(plot_contours([line]).figure, plot_contours([p[:20]]).figure)
    with pytest.raises(CurveError) as info:
        plot_contours([blob, BAD])
    _names_the_forms(info, "contours[1]")
    with pytest.raises(ShapeTreeError, match=r"list of contours.*\[contour\]"):
        plot_contours(blob)  # one contour in place of the list


def test_plot_tree_and_deformations_take_trees_built_from_any_curve(blob) -> None:
    plain = build_shape_tree(_plain(blob), closed=True)
    for form in _forms(blob).values():
        tree = build_shape_tree(form, closed=True)
        _same_figure(plot_tree(tree), plot_tree(plain))
        _same_figure(
            plot_deformations(tree, 0.05, n=2, rng=3), plot_deformations(plain, 0.05, n=2, rng=3)
        )
    for raw in (blob, _plain(blob), geometry.Polygon(_plain(blob))):
        with pytest.raises(ShapeTreeError, match="build_shape_tree"):
            plot_tree(raw)
        with pytest.raises(ShapeTreeError, match="build_shape_tree"):
            plot_deformations(raw, 0.05, n=1)


# ---------------------------------------------------------------- detection


def _same_model(a, b) -> None:
    np.testing.assert_array_equal(a.curve, b.curve)
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.gap_weight, b.gap_weight)
    assert a.closed == b.closed and a.name == b.name


def test_make_model_and_load_model(blob) -> None:
    p = _plain(blob)
    for form in _forms(blob).values():
        _same_model(make_model(form, m=12), make_model(p, m=12))
        _same_model(load_model(form, m=12), load_model(p, m=12))
    free = np.zeros(len(p), bool)
    free[3] = True  # one flag per point, the ring's closing point not counted
    _same_model(make_model(geometry.Polygon(p), m=12, free=free), make_model(p, m=12, free=free))
    line = geometry.LineString(p[:20])
    _same_model(make_model(line, closed=False, m=12), make_model(p[:20], closed=False, m=12))
    for call in (lambda: make_model(BAD), lambda: load_model(BAD)):
        with pytest.raises(CurveError) as info:
            call()
        _names_the_forms(info, "model curve")
    with pytest.raises(CurveError, match="closed curve"):
        make_model(geometry.Polygon(p), closed=False)


@pytest.fixture(scope="module")
def scene():
    """A model and real OpenCV contours of a scene: the shape (broken in two) and a box."""
    t = np.linspace(0, 2 * np.pi, 120, endpoint=False)
    shape = _outline(t, 40.0, (90.0, 80.0))
    (obj, box) = _find_contours(
        (170, 230),
        shape,
        np.array([[165, 30], [215, 30], [215, 140], [165, 140]]),
        approx=cv2.CHAIN_APPROX_NONE,
    )
    k = len(obj)
    pieces = [obj[: k // 2 - 10], obj[k // 2 :], box[: len(box) // 2]]
    model = make_model(_outline(t, 1.0, (0.0, 0.0)), m=16)
    return model, pieces, shape


def _same_detections(a, b) -> None:
    assert len(a) == len(b) > 0
    for x, y in zip(a, b, strict=True):
        assert (x.cost, x.score, x.bbox, x.coverage, x.gaps, x.pieces) == (
            y.cost,
            y.score,
            y.bbox,
            y.coverage,
            y.gaps,
            y.pieces,
        )
        np.testing.assert_array_equal(x.image_points, y.image_points)
        np.testing.assert_array_equal(x.matched, y.matched)


def test_detect_contours_from_opencv(scene) -> None:
    model, pieces, _ = scene
    plain = detect(model, None, contours=[_plain(c) for c in pieces], k=2)
    _same_detections(detect(model, None, contours=pieces, k=2), plain)
    _same_detections(detect(model, None, contours=tuple(pieces), k=2), plain)  # as cv2 gives
    speck = np.array([[[5, 5]]], np.int32)  # cv2.findContours of a one-pixel dot: skipped
    _same_detections(detect(model, None, contours=[*pieces, speck], k=2), plain)
    run_cv = detect_detailed(model, None, contours=pieces, k=2)
    run_np = detect_detailed(model, None, contours=[_plain(c) for c in pieces], k=2)
    assert len(run_cv.contours) == len(run_np.contours) == 3
    for a, b in zip(run_cv.contours, run_np.contours, strict=True):
        np.testing.assert_array_equal(a, b)
    _same_detections(run_cv.detections, run_np.detections)
    _same_figure(plot_detections(run_cv, n_show=2), plot_detections(run_np, n_show=2))


def test_detect_contours_from_shapely(scene) -> None:
    model, pieces, shape = scene
    arrays = [_plain(c) for c in pieces]
    lines = [geometry.LineString(a) for a in arrays]
    _same_detections(
        detect(model, None, contours=lines, k=2), detect(model, None, contours=arrays, k=2)
    )
    # a whole closed boundary as one image contour: a ring is its points first to last
    # (the repeated closing point dropped), like the OpenCV contour of the same boundary
    (whole,) = _find_contours((170, 230), shape, approx=cv2.CHAIN_APPROX_NONE)
    plain = detect(model, None, contours=[_plain(whole)], k=1)
    _same_detections(detect(model, None, contours=[whole], k=1), plain)
    for form in (geometry.Polygon(_plain(whole)), geometry.LinearRing(_plain(whole))):
        _same_detections(detect(model, None, contours=[form], k=1), plain)


def test_detect_models_from_opencv_and_shapely(scene) -> None:
    _, pieces, shape = scene
    (model_cv,) = _find_contours((170, 230), shape, approx=cv2.CHAIN_APPROX_SIMPLE)
    p = _plain(model_cv)
    kw = dict(contours=pieces, k=2, m=16)
    plain = detect(p, None, **kw)
    for form in _forms(model_cv).values():
        _same_detections(detect(form, None, **kw), plain)
        run = detect_detailed(form, None, **kw)
        _same_model(run.model, load_model(p, m=16))


def test_detect_bad_shapes_name_the_accepted_forms(scene) -> None:
    model, pieces, _ = scene
    for call in (detect, detect_detailed):
        with pytest.raises(CurveError) as info:
            call(model, None, contours=[pieces[0], BAD])
        _names_the_forms(info, "contours[1]")
        with pytest.raises(CurveError) as info:
            call(BAD, None, contours=pieces)
        _names_the_forms(info, "model curve")
        for single in (pieces[0], _plain(pieces[0]), geometry.LineString(_plain(pieces[0]))):
            with pytest.raises(ShapeTreeError, match=r"list of contours.*\[contour\]") as info:
                call(model, None, contours=single)
            _names_the_forms(info)
    multi = geometry.MultiLineString([_plain(pieces[0]), _plain(pieces[1])])
    with pytest.raises(CurveError, match="MultiLineString"):
        detect(model, None, contours=[multi])


def test_detect_params_contour_min_points_is_validated(scene) -> None:
    model, pieces, _ = scene
    for bad in (1, 0, -3):
        with pytest.raises(ShapeTreeError, match="contour_min_points must be >= 2"):
            DetectParams(contour_min_points=bad)
        with pytest.raises(ShapeTreeError, match="contour_min_points must be >= 2"):
            detect(model, None, contours=pieces, contour_min_points=bad)  # an override
    for bad in (2.5, "3", True):
        with pytest.raises(ShapeTreeError, match="contour_min_points must be an integer"):
            DetectParams(contour_min_points=bad)
    with pytest.raises(ShapeTreeError, match="contour_max_points"):
        DetectParams(contour_min_points=8, contour_max_points=5)
    assert DetectParams(contour_min_points=np.int64(2)).contour_min_points == 2
    assert detect(model, None, contours=pieces, k=1, contour_min_points=2)
