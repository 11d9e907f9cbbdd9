"""Curves as other libraries hand them over: OpenCV contours and ``__geo_interface__`` objects.

Every public function reads its curves with ``shapetree.curves.as_curve``. The NumPy-only tests
build the ``(n, 1, 2)`` arrays and geo-interface objects by hand, so the behaviour is tested
without OpenCV or shapely; the others use real ``cv2.findContours`` output and shapely objects.
"""

from __future__ import annotations

import numpy as np
import pytest

from shapetree import CurveError
from shapetree.curves import (
    as_curve,
    curve_length,
    load_points,
    orient,
    resample,
    signed_area,
    smooth,
)
from shapetree.matching import match, prepare_model, prepare_target
from shapetree.retrieval import distance_matrix
from shapetree.tree import build_shape_tree

ACCEPTED = [
    "(n, 2)",
    "x + iy",
    "(n, 1, 2)",
    "LineString",
    "LinearRing",
    "Polygon",
    "__geo_interface__",
]


def _blob(n: int = 40, cx: float = 50.0, cy: float = 40.0) -> np.ndarray:
    """An integer pixel outline, (n, 2), counter-clockwise, no symmetry."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 20 * (1 + 0.3 * np.cos(3 * t) + 0.15 * np.sin(2 * t))
    return np.round(np.c_[cx + r * np.cos(t), cy + r * np.sin(t)]).astype(np.int32)


def _as_cv(points: np.ndarray) -> np.ndarray:
    """An (n, 2) integer array in OpenCV's contour layout (n, 1, 2), int32."""
    return np.ascontiguousarray(np.asarray(points, dtype=np.int32)[:, None, :])


class Geo:
    """A minimal geo-interface object (what shapely, geopandas, ... expose)."""

    def __init__(self, kind: str, coordinates) -> None:
        self.__geo_interface__ = {"type": kind, "coordinates": coordinates}


def _ring(points: np.ndarray) -> list[list[float]]:
    """GeoJSON ring: the first point repeated at the end."""
    p = np.asarray(points, dtype=float).tolist()
    return [*p, p[0]]


# ---------------------------------------------------------------- OpenCV layout, NumPy only


def test_opencv_layout_equals_plain_float_array() -> None:
    blob = _blob()
    cv = _as_cv(blob)
    assert cv.shape == (40, 1, 2) and cv.dtype == np.int32
    out = as_curve(cv, closed=True)
    assert out.dtype == np.float64 and out.shape == (40, 2)
    np.testing.assert_array_equal(out, blob.astype(np.float64))
    assert not np.shares_memory(out, cv)
    # float contours (cv2.approxPolyDP on float input, saved files) too
    np.testing.assert_array_equal(as_curve(cv.astype(np.float32), closed=True), out)


def test_opencv_layout_through_every_curve_function(tmp_path) -> None:
    blob = _blob()
    plain = blob.astype(np.float64)
    cv = _as_cv(blob)
    np.testing.assert_array_equal(resample(cv, 25, closed=True), resample(plain, 25, closed=True))
    np.testing.assert_array_equal(resample(cv, 9, closed=False), resample(plain, 9, closed=False))
    np.testing.assert_array_equal(smooth(cv, 0.01, closed=True), smooth(plain, 0.01, closed=True))
    assert curve_length(cv, closed=True) == curve_length(plain, closed=True)
    assert signed_area(cv) == signed_area(plain) > 0
    np.testing.assert_array_equal(orient(cv, "cw"), orient(plain, "cw"))
    np.save(tmp_path / "contour.npy", cv)  # a contour saved as OpenCV gives it
    np.testing.assert_array_equal(load_points(tmp_path / "contour.npy"), plain)


def test_opencv_layout_through_matching_and_trees() -> None:
    a, b = _blob(), _blob(36, 10.0, -5.0)
    b = np.round(b * np.array([1.0, 0.7])).astype(np.int32)
    pa, pb = a.astype(float), b.astype(float)
    res_cv = match(_as_cv(a), _as_cv(b), "paper")
    res_np = match(pa, pb, "paper")
    assert res_cv.cost == res_np.cost > 0
    np.testing.assert_array_equal(res_cv.a_to_b, res_np.a_to_b)
    assert match(_as_cv(a), pa, "paper").cost == pytest.approx(0.0, abs=1e-9)
    t_cv, t_np = build_shape_tree(_as_cv(a), closed=True), build_shape_tree(pa, closed=True)
    np.testing.assert_array_equal(t_cv.points, t_np.points)
    np.testing.assert_array_equal(t_cv.coords, t_np.coords)
    np.testing.assert_array_equal(prepare_model(_as_cv(a)).points, prepare_model(pa).points)
    np.testing.assert_array_equal(prepare_target(_as_cv(b)).points, prepare_target(pb).points)
    kw = dict(n_points=20, progress=False, workers=1)
    np.testing.assert_array_equal(
        distance_matrix([_as_cv(a), _as_cv(b)], **kw), distance_matrix([pa, pb], **kw)
    )


def test_wrong_shapes_name_the_accepted_forms() -> None:
    for bad, shape in [
        (np.zeros((5, 3)), "(5, 3)"),
        (np.zeros((5, 2, 1)), "(5, 2, 1)"),
        (np.zeros((1, 5, 2)), "(1, 5, 2)"),
        (np.arange(6.0), "(6,)"),
    ]:
        with pytest.raises(CurveError) as info:
            as_curve(bad, closed=True, name="my-shape")
        msg = str(info.value)
        assert "my-shape" in msg and shape in msg
        for word in ACCEPTED:
            assert word in msg


def test_a_list_of_contours_is_refused_with_a_hint() -> None:
    c = _as_cv(_blob())
    for contours in [(c,), [c, c], [c, c[:10]]]:  # what findContours returns: a sequence
        with pytest.raises(CurveError, match="list of OpenCV contours: pass one of them"):
            as_curve(contours, closed=True)


def test_a_row_of_x_and_a_row_of_y_gets_a_transpose_hint() -> None:
    with pytest.raises(CurveError, match=r"shape \(2, 40\).*pass its transpose"):
        as_curve(_blob().T, closed=True)


# ---------------------------------------------------------------- complex numbers x + iy


def test_a_complex_vector_is_the_curve_x_plus_iy() -> None:
    a, b = _blob().astype(float), _blob(36, 10.0, -5.0).astype(float)
    za, zb = a[:, 0] + 1j * a[:, 1], b[:, 0] + 1j * b[:, 1]
    np.testing.assert_array_equal(as_curve(za, closed=True), a)
    np.testing.assert_array_equal(as_curve(list(za), closed=True), a)  # a list of complex
    assert match(za, zb).cost == match(a, b).cost > 0
    np.testing.assert_array_equal(
        build_shape_tree(za, closed=True).coords, build_shape_tree(a, closed=True).coords
    )
    assert curve_length(za, closed=True) == curve_length(a, closed=True)


def test_complex_pairs_are_refused_not_truncated() -> None:
    a = _blob().astype(float)
    z = a + 0.5j  # (n, 2) complex: dropping the imaginary part would be a silent wrong answer
    with pytest.raises(CurveError, match=r"complex coordinates in an array of shape \(40, 2\)"):
        match(z, a)
    with pytest.raises(CurveError, match="complex"):
        as_curve(z, closed=True, name="z")
    # an imaginary part that is exactly zero loses nothing
    np.testing.assert_array_equal(as_curve(a + 0j, closed=True), a)


def test_distinct_points_are_counted_anywhere_on_the_curve() -> None:
    back_and_forth = np.array([[0.0, 0.0], [1.0, 2.0], [0.0, 0.0], [1.0, 2.0]])
    with pytest.raises(CurveError, match=r"fewer than 3 distinct points \(2\)"):
        as_curve(back_and_forth, closed=False)
    assert as_curve(back_and_forth, closed=False, min_points=2).shape == (4, 2)
    signed_zero = np.array([[0.0, 1.0], [-0.0, 1.0], [0.0, 1.0], [2.0, 3.0], [4.0, 0.0]])
    with pytest.raises(CurveError, match=r"fewer than 4 distinct points \(3\)"):
        as_curve(signed_zero, closed=True, min_points=4)  # -0.0 and 0.0 are one coordinate
    with pytest.raises(CurveError, match="zero length"):
        as_curve(np.ones((5, 2)) * [3.0, -1.0], closed=True)


# ---------------------------------------------------------------- geo interface, NumPy only


def test_geo_polygon_is_its_exterior_without_the_repeated_point() -> None:
    blob = _blob().astype(float)
    hole = [[45.0, 35.0], [55.0, 35.0], [50.0, 45.0], [45.0, 35.0]]
    for geo in [
        Geo("Polygon", [_ring(blob)]),
        Geo("Polygon", [_ring(blob), hole]),  # holes are ignored
        Geo("LinearRing", _ring(blob)),
        {"type": "Polygon", "coordinates": [_ring(blob)]},  # a GeoJSON dict itself
        {
            "type": "Feature",
            "properties": {},
            "geometry": {"type": "Polygon", "coordinates": [_ring(blob)]},
        },
    ]:
        np.testing.assert_array_equal(as_curve(geo, closed=True), blob)
        np.testing.assert_array_equal(orient(geo, "keep"), blob)
        assert curve_length(geo, closed=True) == pytest.approx(curve_length(blob, closed=True))
        assert signed_area(geo) == pytest.approx(signed_area(blob))


def test_geo_linestring_is_an_open_curve_and_z_is_ignored() -> None:
    line = np.array([[0.0, 0.0], [3.0, 1.0], [5.0, 4.0], [6.0, 9.0]])
    np.testing.assert_array_equal(as_curve(Geo("LineString", line.tolist()), closed=False), line)
    with_z = np.c_[line, np.arange(4.0)].tolist()
    np.testing.assert_array_equal(as_curve(Geo("LineString", with_z), closed=False), line)
    # a LineString may be given as a closed curve, like an array
    np.testing.assert_array_equal(as_curve(Geo("LineString", _ring(line)), closed=True), line)


@pytest.mark.parametrize(
    ("geo", "words"),
    [
        (Geo("MultiPolygon", []), ["MultiPolygon", "several", "one of its parts", "largest"]),
        (Geo("MultiLineString", []), ["MultiLineString", "one of its parts"]),
        (Geo("GeometryCollection", []), ["GeometryCollection"]),
        (Geo("Point", [1.0, 2.0]), ["Point", "not a curve"]),
        (Geo("Polygon", []), ["Polygon", "empty"]),
        (Geo("LineString", []), ["LineString", "empty"]),
    ],
)
def test_geo_refusals_name_the_problem(geo, words) -> None:
    with pytest.raises(CurveError) as info:
        as_curve(geo, closed=True, name="parcel 7")
    msg = str(info.value)
    assert "parcel 7" in msg
    for word in words:
        assert word in msg


def test_a_ring_is_not_an_open_curve() -> None:
    ring = Geo("Polygon", [_ring(_blob())])
    with pytest.raises(CurveError, match="closed curve.*closed=True.*LineString"):
        as_curve(ring, closed=False)
    with pytest.raises(CurveError, match="closed curve"):
        curve_length(ring, closed=False)


# ---------------------------------------------------------------- short open polylines


def test_min_points_lets_open_segments_through() -> None:
    seg = [[0.0, 0.0], [3.0, 4.0]]
    with pytest.raises(CurveError, match="fewer than 3 distinct"):
        as_curve(seg, closed=False)
    np.testing.assert_array_equal(as_curve(seg, closed=False, min_points=2), seg)
    with pytest.raises(CurveError, match="fewer than 4 distinct"):
        as_curve([[0, 0], [1, 0], [1, 1]], closed=False, min_points=4)
    for bad, closed in [(2, True), (1, False), (2.0, False), (True, False)]:
        with pytest.raises(CurveError, match="min_points must be an integer"):
            as_curve(seg * 2, closed=closed, min_points=bad)
    with pytest.raises(CurveError, match="zero length"):
        as_curve([[1.0, 1.0], [1.0, 1.0]], closed=False, min_points=2)


# ---------------------------------------------------------------- real OpenCV and shapely


def _cv_contours():
    cv2 = pytest.importorskip("cv2")
    img = np.zeros((120, 160), np.uint8)
    cv2.circle(img, (45, 60), 30, 255, -1)
    cv2.rectangle(img, (95, 20), (145, 100), 255, -1)
    contours, _ = cv2.findContours(img, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    assert len(contours) == 2
    disk, rect = sorted(contours, key=lambda c: c[:, 0, 0].min())
    return disk, rect


def test_real_findcontours_output() -> None:
    disk, rect = _cv_contours()
    for c in (disk, rect):
        assert c.ndim == 3 and c.shape[1:] == (1, 2) and c.dtype.kind == "i"
        np.testing.assert_array_equal(as_curve(c, closed=True), c[:, 0, :].astype(np.float64))
    # the disk is round: points ~30 px from its centre
    d = as_curve(disk, closed=True)
    assert np.all(np.abs(np.hypot(d[:, 0] - 45, d[:, 1] - 60) - 30) < 1.5)
    assert curve_length(rect, closed=True) == pytest.approx(2 * (50 + 80))
    t = build_shape_tree(resample(disk, 32, closed=True), closed=True)
    assert build_shape_tree(disk, closed=True).points.shape == (len(disk), 2)
    assert t.points.shape == (32, 2)


def test_real_shapely_objects() -> None:
    geometry = pytest.importorskip("shapely.geometry")
    pts = [(0.0, 0.0), (4.0, 0.0), (4.0, 3.0), (1.0, 5.0)]
    ring = np.array(pts)
    poly = geometry.Polygon(pts, holes=[[(1.0, 1.0), (2.0, 1.0), (2.0, 2.0)]])
    np.testing.assert_array_equal(as_curve(poly, closed=True), ring)
    np.testing.assert_array_equal(as_curve(geometry.LinearRing(pts), closed=True), ring)
    np.testing.assert_array_equal(as_curve(poly.exterior, closed=True), ring)
    line = geometry.LineString(pts)
    np.testing.assert_array_equal(as_curve(line, closed=False), ring)
    np.testing.assert_array_equal(resample(line, 9, closed=False)[[0, -1]], ring[[0, -1]])
    assert signed_area(poly) == pytest.approx(geometry.Polygon(pts).area)  # hole ignored
    assert curve_length(poly, closed=True) == pytest.approx(poly.exterior.length)
    multi = geometry.MultiPolygon([poly, geometry.box(10, 10, 12, 12)])
    with pytest.raises(CurveError, match="MultiPolygon.*one of its parts"):
        as_curve(multi, closed=True)
    with pytest.raises(CurveError, match="Point geometry is not a curve"):
        as_curve(geometry.Point(1, 2), closed=True)
    with pytest.raises(CurveError, match="empty"):
        as_curve(geometry.Polygon(), closed=True)
    t = build_shape_tree(poly.buffer(2.0), closed=True)
    assert t.points.shape[0] == len(poly.buffer(2.0).exterior.coords) - 1


def test_match_and_distance_matrix_on_contours_and_polygons() -> None:
    geometry = pytest.importorskip("shapely.geometry")
    disk, _ = _cv_contours()
    # a polygon of another shape, counter-clockwise in the same frame as the contour
    blob = _blob(60, 50.0, 50.0).astype(float)
    if signed_area(blob) * signed_area(disk) < 0:
        blob = blob[::-1].copy()
    polygon = geometry.Polygon(blob)
    plain_disk, plain_poly = disk[:, 0, :].astype(float), blob
    res = match(disk, polygon, "paper")
    ref = match(plain_disk, plain_poly, "paper")
    assert res.cost == ref.cost > 0
    np.testing.assert_array_equal(res.a_to_b, ref.a_to_b)
    d = distance_matrix([disk, polygon], n_points=20, progress=False, workers=1)
    d_ref = distance_matrix([plain_disk, plain_poly], n_points=20, progress=False, workers=1)
    assert d.shape == (2, 2)
    np.testing.assert_array_equal(d, d_ref)
    assert np.all(np.abs(np.diag(d)) < 1e-9) and min(d[0, 1], d[1, 0]) > 1e-3
