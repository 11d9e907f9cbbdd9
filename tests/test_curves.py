"""Tests of shapetree.curves: validation, geometry, resampling, point files, load_curve."""

from __future__ import annotations

import json

import numpy as np
import pytest

from shapetree import CurveError, ImageError, ShapeTreeError
from shapetree.curves import (
    as_curve,
    curve_length,
    load_curve,
    load_points,
    orient,
    resample,
    signed_area,
    smooth,
)

SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])  # ccw in a y-up frame


def circle(n: int, r: float = 1.0, cx: float = 0.0, cy: float = 0.0) -> np.ndarray:
    t = 2 * np.pi * np.arange(n) / n
    return np.column_stack([cx + r * np.cos(t), cy + r * np.sin(t)])


# ---------------------------------------------------------------- as_curve


def test_as_curve_returns_float64_copy():
    pts = [[0, 0], [2, 0], [2, 1]]
    out = as_curve(pts, closed=False)
    assert out.dtype == np.float64 and out.shape == (3, 2)
    src = np.array(pts, dtype=np.float64)
    out2 = as_curve(src, closed=False)
    out2[0, 0] = 99
    assert src[0, 0] == 0


def test_as_curve_drops_repeated_endpoint_only_when_closed():
    pts = np.vstack([SQUARE, SQUARE[:1]])
    assert as_curve(pts, closed=True).shape == (4, 2)
    np.testing.assert_array_equal(as_curve(pts, closed=True), SQUARE)
    assert as_curve(pts, closed=False).shape == (5, 2)


def test_as_curve_drops_consecutive_duplicates():
    pts = np.array([[0, 0], [0, 0], [1, 0], [1, 0], [1, 0], [1, 1], [0, 1], [0, 1]], float)
    np.testing.assert_array_equal(as_curve(pts, closed=False), SQUARE)
    # Non-consecutive repeats are legitimate (a curve may pass a point twice).
    assert as_curve([[0, 0], [1, 0], [0, 0], [0, 1]], closed=False).shape == (4, 2)


@pytest.mark.parametrize(
    ("points", "words"),
    [
        (np.zeros((5, 3)), ["(n, 2)", "(5, 3)", "shape"]),
        (np.arange(6.0), ["1-D", "(6,)"]),
        (np.zeros((0, 2)), ["empty"]),
        ([[0, 0], [1, "a"], [2, 2]], ["numeric"]),
        ([[0, 0], [1, 1], [np.nan, 2], [3, 0]], ["row 2", "NaN"]),
        ([[0, 0], [1, 1], [2, 2], [3, np.inf]], ["row 3", "inf"]),
        ([[1, 1], [1, 1], [1, 1]], ["zero length"]),
        ([[0, 0], [1, 1], [0, 0], [1, 1]], ["fewer than 3 distinct"]),
    ],
)
def test_as_curve_errors(points, words):
    with pytest.raises(CurveError) as info:
        as_curve(points, closed=False, name="my-shape")
    msg = str(info.value)
    assert "my-shape" in msg
    for word in words:
        assert word in msg
    assert isinstance(info.value, ShapeTreeError) and isinstance(info.value, ValueError)


def test_closed_curve_of_two_points_plus_repeat_is_rejected():
    with pytest.raises(CurveError, match="fewer than 3 distinct"):
        as_curve([[0, 0], [1, 0], [0, 0]], closed=True)


def test_closed_curve_on_one_line_is_rejected_open_line_is_kept():
    """A closed curve whose points all lie on one line encloses nothing: refused with a
    sentence naming it (it used to get a finite cost and no warning); the same points as an
    open curve are a straight line, kept; a thin but real outline is kept."""
    t = np.linspace(0, 1, 20)
    line = np.c_[3 + 2 * t, -1 + 0.5 * t]
    for pts in (line, np.r_[line, line[::-1][1:-1]]):  # a segment, and one traced back
        with pytest.raises(CurveError, match="my-line.*one straight line.*closed=False"):
            as_curve(pts, closed=True, name="my-line")
    assert as_curve(line, closed=False).shape == (20, 2)
    thin = np.r_[line, line[::-1] + [0, 1e-6]]
    assert as_curve(thin, closed=True).shape == (40, 2)


# ---------------------------------------------------------------- length, area, orientation


def test_curve_length():
    assert curve_length(SQUARE, closed=True) == pytest.approx(4.0)
    assert curve_length(SQUARE, closed=False) == pytest.approx(3.0)
    assert curve_length(circle(2000, r=3.0), closed=True) == pytest.approx(6 * np.pi, rel=1e-5)


def test_signed_area_sign_and_value():
    assert signed_area(SQUARE) == pytest.approx(1.0)
    assert signed_area(SQUARE[::-1]) == pytest.approx(-1.0)
    assert signed_area(circle(4000, r=2.0, cx=5, cy=-7)) == pytest.approx(4 * np.pi, rel=1e-5)


@pytest.mark.parametrize("start", [SQUARE, SQUARE[::-1].copy()])
def test_orient(start):
    ccw = orient(start, "ccw")
    cw = orient(start, "cw")
    assert signed_area(ccw) > 0 and signed_area(cw) < 0
    # Reversal keeps the first point first and the same vertex set.
    np.testing.assert_array_equal(ccw[0], start[0])
    np.testing.assert_array_equal(cw[0], start[0])
    assert {tuple(p) for p in ccw} == {tuple(p) for p in start}
    np.testing.assert_array_equal(orient(start, "keep"), start)
    np.testing.assert_array_equal(orient(start, None), start)


def test_orient_reverse_order_exact():
    cw = SQUARE[[0, 3, 2, 1]]
    np.testing.assert_array_equal(orient(cw, "ccw"), SQUARE)
    np.testing.assert_array_equal(orient(SQUARE, "cw"), cw)


def test_orient_bad_value():
    with pytest.raises(CurveError, match="orientation"):
        orient(SQUARE, "clockwise")


# ---------------------------------------------------------------- resample


def _chords(pts: np.ndarray, closed: bool) -> np.ndarray:
    if closed:
        pts = np.vstack([pts, pts[:1]])
    return np.hypot(*np.diff(pts, axis=0).T)


def test_resample_closed_rectangle_is_uniform():
    rect = np.array([[0, 0], [3, 0], [3, 1], [0, 1]], float)  # perimeter 8
    out = resample(rect, 80, closed=True)
    assert out.shape == (80, 2)
    np.testing.assert_array_equal(out[0], rect[0])
    d = _chords(out, closed=True)
    assert d.std() / d.mean() < 1e-6
    assert d.mean() == pytest.approx(0.1)
    assert curve_length(out, closed=True) == pytest.approx(8.0)
    # No repeated endpoint, and every sample lies on the rectangle.
    assert not np.allclose(out[-1], out[0])
    on_edge = np.isclose(out[:, 0], 0) | np.isclose(out[:, 0], 3)
    on_edge |= np.isclose(out[:, 1], 0) | np.isclose(out[:, 1], 1)
    assert on_edge.all()


def test_resample_open_polyline_is_uniform_and_keeps_ends():
    line = np.array([[0, 0], [2, 0], [2, 3], [7, 3]], float)  # length 10
    out = resample(line, 21, closed=False)
    np.testing.assert_array_equal(out[0], line[0])
    np.testing.assert_array_equal(out[-1], line[-1])
    d = _chords(out, closed=False)
    assert d.std() / d.mean() < 1e-6
    assert d.mean() == pytest.approx(0.5)


def test_resample_arc_length_is_uniform_for_any_n():
    """Arc-length positions of the samples are exactly uniform (corners need not be sampled)."""
    rng = np.random.default_rng(0)
    poly = circle(7, r=5.0) + rng.normal(scale=0.3, size=(7, 2))
    out = resample(poly, 53, closed=True)
    closed_poly = np.vstack([poly, poly[:1]])
    s = np.concatenate([[0], np.cumsum(_chords(poly, closed=True))])
    # Arc-length position of each sample: find its segment and the offset along it.
    pos = []
    for p in out:
        for i in range(len(poly)):
            a, b = closed_poly[i], closed_poly[i + 1]
            t = np.dot(p - a, b - a) / np.dot(b - a, b - a)
            if -1e-9 <= t <= 1 + 1e-9 and np.linalg.norm(a + t * (b - a) - p) < 1e-9:
                pos.append(s[i] + t * np.linalg.norm(b - a))
                break
    assert len(pos) == len(out)
    gaps = np.diff(pos)
    assert gaps.std() / gaps.mean() < 1e-6
    assert gaps.mean() == pytest.approx(s[-1] / 53)


def test_resample_circle_preserves_length_and_radius():
    fine = circle(1000, r=10.0)
    out = resample(fine, 64, closed=True)
    assert np.hypot(*out.T) == pytest.approx(10.0, abs=1e-3)
    assert curve_length(out, closed=True) == pytest.approx(2 * np.pi * 10, rel=2e-3)


def test_resample_ignores_duplicates_and_repeated_endpoint():
    messy = np.vstack([SQUARE[:1], SQUARE, SQUARE[:1]])
    np.testing.assert_allclose(resample(messy, 8, closed=True), resample(SQUARE, 8, closed=True))


@pytest.mark.parametrize("n", [2, 0, -5, 3.5, "10", True])
def test_resample_bad_n(n):
    with pytest.raises(CurveError, match="n must be an integer >= 3"):
        resample(SQUARE, n, closed=True)


def test_resample_accepts_numpy_integer():
    assert resample(SQUARE, np.int64(12), closed=True).shape == (12, 2)


def test_resample_open_segment_and_two_point_outputs() -> None:
    seg = np.array([[0.0, 0.0], [3.0, 4.0]])
    np.testing.assert_allclose(
        resample(seg, 6, closed=False), np.linspace(0, 1, 6)[:, None] * seg[1]
    )
    np.testing.assert_array_equal(resample(seg, 2, closed=False), seg)
    line = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0], [1.0, 2.0], [4.0, 2.0]])
    np.testing.assert_array_equal(resample(line, 2, closed=False), line[[0, -1]])
    with pytest.raises(CurveError, match="n must be an integer >= 2 for an open curve"):
        resample(line, 1, closed=False)
    with pytest.raises(CurveError, match="n must be an integer >= 3 for a closed curve"):
        resample(line, 2, closed=True)
    with pytest.raises(CurveError, match="fewer than 3 distinct"):
        resample(seg, 5, closed=True)  # a closed curve still needs 3 points


def test_resample_open_matches_linear_interpolation_in_arclength():
    # the open-curve resampling detection uses (it replaced detection.resample_polyline)
    rng = np.random.default_rng(3)
    for k in (2, 3, 7, 40):
        pts = np.cumsum(rng.normal(size=(k, 2)), axis=0)
        pts = np.repeat(pts, rng.integers(1, 3, size=k), axis=0)  # repeated points are kept
        cum = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
        for n in (2, 3, 11, 100):
            t = np.linspace(0.0, cum[-1], n)
            ref = np.c_[np.interp(t, cum, pts[:, 0]), np.interp(t, cum, pts[:, 1])]
            out = resample(pts, n, closed=False)
            np.testing.assert_allclose(out, ref, rtol=0, atol=1e-12)
            np.testing.assert_array_equal(out[[0, -1]], pts[[0, -1]])


# ---------------------------------------------------------------- load_points


@pytest.mark.parametrize(
    ("name", "text"),
    [
        ("a.csv", "x,y\n0,0\n1,0\n1,1\n0,1\n"),
        ("b.csv", "0, 0\n1, 0\n1, 1\n0, 1\n"),
        ("c.txt", "# a comment\n0 0\n1\t0\n\n1   1\n0 1\n"),
        ("d.txt", "x y\n0.0 0.0\n1e0 0\n1 1.0\n0 1\n"),
        ("e.dat", "0;0\n1;0\n1;1\n0;1\n"),
    ],
)
def test_load_points_text(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    pts = load_points(path)
    assert pts.dtype == np.float64
    np.testing.assert_array_equal(pts, SQUARE)


def test_load_points_npy_and_json(tmp_path):
    np.save(tmp_path / "s.npy", SQUARE)
    np.testing.assert_array_equal(load_points(tmp_path / "s.npy"), SQUARE)
    np.save(tmp_path / "z.npy", SQUARE[:, 0] + 1j * SQUARE[:, 1])  # points x + iy
    np.testing.assert_array_equal(load_points(tmp_path / "z.npy"), SQUARE)
    np.save(tmp_path / "zz.npy", SQUARE + 1j)
    with pytest.raises(CurveError, match="complex coordinates"):
        load_points(tmp_path / "zz.npy")
    (tmp_path / "l.json").write_text(json.dumps(SQUARE.tolist()))
    np.testing.assert_array_equal(load_points(tmp_path / "l.json"), SQUARE)
    (tmp_path / "o.json").write_text(json.dumps({"points": SQUARE.tolist(), "closed": True}))
    np.testing.assert_array_equal(load_points(str(tmp_path / "o.json")), SQUARE)


@pytest.mark.parametrize(
    ("name", "content", "words"),
    [
        ("missing.csv", None, ["not found"]),
        ("three.csv", "0,0,0\n1,1,1\n", ["line 1", "3 values"]),
        ("words.csv", "x,y\n0,0\nfoo,bar\n", ["line 3", "not numeric"]),
        ("empty.txt", "", ["no points"]),
        ("nan.csv", "0,0\n1,nan\n2,2\n", ["row 1", "NaN"]),
        ("bad.json", "{not json", ["JSON"]),
        ("nokey.json", '{"pts": [[0, 0]]}', ["'points'"]),
        ("triples.json", "[[0, 0, 1], [1, 1, 1]]", ["[x, y]"]),
        ("closed.json", '{"points": [[0, 0], [1, 0], [1, 1]], "closed": "yes"}', ["closed"]),
        ("bad.npy", "this is not an npy file", [".npy"]),
        ("shape.npy", np.zeros((4, 3)), ["(4, 3)"]),
        ("shape.png", "not really", ["image"]),
    ],
)
def test_load_points_errors(tmp_path, name, content, words):
    path = tmp_path / name
    if isinstance(content, np.ndarray):
        np.save(path, content)
    elif content is not None:
        path.write_text(content)
    with pytest.raises(CurveError) as info:
        load_points(path)
    msg = str(info.value)
    assert name in msg
    for word in words:
        assert word in msg


def test_load_points_directory(tmp_path):
    with pytest.raises(CurveError, match="not a file"):
        load_points(tmp_path)


# ---------------------------------------------------------------- load_curve (point files)


def test_load_curve_point_file_defaults_to_open(tmp_path):
    path = tmp_path / "line.csv"
    path.write_text("0,0\n1,0\n1,1\n0,1\n")
    pts, closed = load_curve(path)
    assert closed is False
    np.testing.assert_array_equal(pts, SQUARE)  # open curves are never reoriented


def test_load_curve_closed_orients_and_resamples(tmp_path):
    path = tmp_path / "sq.npy"
    cw = np.vstack([SQUARE[::-1], SQUARE[-1:]])  # clockwise, with a repeated endpoint
    np.save(path, cw)
    pts, closed = load_curve(path, closed=True)
    assert closed is True and pts.shape == (4, 2) and signed_area(pts) > 0
    np.testing.assert_array_equal(pts[0], cw[0])
    pts, _ = load_curve(path, closed=True, orientation="cw")
    assert signed_area(pts) < 0
    pts, _ = load_curve(path, closed=True, n_points=40)
    assert pts.shape == (40, 2)
    d = _chords(pts, closed=True)
    assert d.std() / d.mean() < 1e-6


def test_load_curve_json_closed_key(tmp_path):
    path = tmp_path / "c.json"
    path.write_text(json.dumps({"points": SQUARE[::-1].tolist(), "closed": True}))
    pts, closed = load_curve(path)
    assert closed is True and signed_area(pts) > 0
    _, closed = load_curve(path, closed=False)  # the argument wins over the file
    assert closed is False


def test_load_curve_invalid_curve_names_file(tmp_path):
    path = tmp_path / "flat.csv"
    path.write_text("1,1\n1,1\n1,1\n")
    with pytest.raises(CurveError, match="flat.csv.*zero length"):
        load_curve(path)


def test_load_curve_missing_image_is_image_error(tmp_path):
    with pytest.raises(ImageError, match="not found"):
        load_curve(tmp_path / "nothing.png")


# ---------------------------------------------------------------- smooth


def test_smooth_circle_shrinks_by_the_gaussian_factor():
    c = circle(2000, r=3.0)
    for sigma in (0.005, 0.02, 0.05):
        out = smooth(c, sigma, closed=True)
        r = np.hypot(*out.T)
        expected = 3.0 * np.exp(-((2 * np.pi * sigma) ** 2) / 2)
        assert r.mean() == pytest.approx(expected, rel=1e-4)
        assert r.std() < 1e-6


def test_smooth_removes_fine_ripple_but_keeps_the_shape():
    # fine square-wave ripple on a circle (like a pixel staircase): ripple goes, circle stays
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    wobbly = np.c_[np.cos(t), np.sin(t)] * (1 + 0.01 * np.sign(np.sin(80 * t)))[:, None]
    out = smooth(wobbly, 0.01, closed=True)
    r = np.hypot(*out.T)
    assert r.std() < 0.1 * np.hypot(*wobbly.T).std()
    assert abs(r.mean() - 1.0) < 0.01


def test_smooth_open_keeps_ends_and_zero_is_identity():
    x = np.linspace(0, 10, 200)
    line = np.c_[x, 0.1 * np.sin(7 * x)]
    out = smooth(line, 0.02, closed=False)
    assert np.allclose(out[0], line[0]) and np.allclose(out[-1], line[-1])
    assert np.abs(out[:, 1]).max() < np.abs(line[:, 1]).max()
    assert np.array_equal(smooth(line, 0.0, closed=False), as_curve(line, closed=False))


@pytest.mark.parametrize("sigma", [-0.1, 0.5, float("nan"), "a", True])
def test_smooth_bad_sigma(sigma):
    with pytest.raises(CurveError, match="sigma"):
        smooth(circle(20), sigma, closed=True)


def test_resample_phase_interleaves_samplings():
    """Phase p/P starts p/P of a spacing later: P phases interleave into the P*n sampling."""
    rng = np.random.default_rng(4)
    poly = circle(9, r=3.0) + rng.normal(scale=0.2, size=(9, 2))
    fine = resample(poly, 24, closed=True)
    for p in range(3):
        np.testing.assert_allclose(resample(poly, 8, closed=True, phase=p / 3), fine[p::3])
    with pytest.raises(CurveError, match="phase must be in"):
        resample(poly, 8, closed=True, phase=1.0)
    with pytest.raises(CurveError, match="closed curves only"):
        resample(poly, 8, closed=False, phase=0.5)
