"""Bookstein coordinates and Procrustes dif (paper §2.1, §3)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shapetree.geometry import bookstein, from_bookstein, procrustes_dif, triangle_dif


def test_bookstein_maps_base_points_to_fixed_frame():
    p1, p2 = np.array([3.0, 1.0]), np.array([5.0, 4.0])
    np.testing.assert_allclose(bookstein(p1, p2, p1), [-0.5, 0.0], atol=1e-15)
    np.testing.assert_allclose(bookstein(p1, p2, p2), [0.5, 0.0], atol=1e-15)
    # the midpoint of the base maps to the origin, a perpendicular offset to the y axis
    np.testing.assert_allclose(bookstein(p1, p2, (p1 + p2) / 2), [0.0, 0.0], atol=1e-15)
    perp = (p1 + p2) / 2 + np.array([-3.0, 2.0])  # (2, 3) rotated by +90 degrees
    np.testing.assert_allclose(bookstein(p1, p2, perp), [0.0, 1.0], atol=1e-15)


def test_bookstein_rejects_equal_base_points():
    with pytest.raises(ValueError, match="distinct"):
        bookstein([1, 1], [1, 1], [0, 0])


coords = st.floats(-100, 100, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(st.lists(coords, min_size=6, max_size=6), coords, st.floats(0.1, 10), coords, coords)
def test_bookstein_invariant_to_similarity(xs, angle, scale, tx, ty):
    p = np.array(xs).reshape(3, 2)
    if np.hypot(*(p[1] - p[0])) < 1e-3:
        return
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    q = scale * p @ rot.T + [tx, ty]
    u = bookstein(p[0], p[1], p[2])
    v = bookstein(q[0], q[1], q[2])
    np.testing.assert_allclose(u, v, atol=1e-7 * (1 + np.abs(u).max()))
    np.testing.assert_allclose(from_bookstein(q[0], q[1], u), q[2], atol=1e-6 * (1 + abs(q).max()))


def test_procrustes_dif_values():
    # identical shapes: 0; dif is bounded by 1 and symmetric
    rng = np.random.default_rng(0)
    u, v = rng.normal(size=(50, 2)), rng.normal(size=(50, 2))
    np.testing.assert_allclose(procrustes_dif(u, u), 0, atol=1e-15)
    d = procrustes_dif(u, v)
    assert np.all((d >= 0) & (d <= 1))
    np.testing.assert_allclose(d, procrustes_dif(v, u), atol=1e-15)
    # mirror images are different shapes unless the triangle is symmetric
    assert procrustes_dif([0.3, 0.4], [0.3, -0.4]) > 0.1


def test_procrustes_dif_matches_explicit_procrustes_fit():
    """1 - |<z,w>|^2 equals the residual of the optimal similarity fit of unit triangles."""
    rng = np.random.default_rng(1)
    for _ in range(20):
        a, b = rng.normal(size=(3, 2)), rng.normal(size=(3, 2))
        za = (a[:, 0] + 1j * a[:, 1]) - (a[:, 0] + 1j * a[:, 1]).mean()
        zb = (b[:, 0] + 1j * b[:, 1]) - (b[:, 0] + 1j * b[:, 1]).mean()
        za /= np.linalg.norm(za)
        zb /= np.linalg.norm(zb)
        # best complex scale-rotation beta minimising |zb - beta za|^2
        beta = np.vdot(za, zb)
        resid = np.linalg.norm(zb - beta * za) ** 2
        tri_a, tri_b = a[[0, 2, 1]], b[[0, 2, 1]]  # (first, middle, last) order
        assert triangle_dif(tri_a, tri_b) == pytest.approx(resid, abs=1e-12)
        u = bookstein(a[0], a[1], a[2])
        v = bookstein(b[0], b[1], b[2])
        assert procrustes_dif(u, v) == pytest.approx(resid, abs=1e-12)


def test_triangle_dif_degenerate_triangles():
    # first == last still compares shapes; a point triangle is at distance 1
    t1 = np.array([[0, 0], [1, 0], [0, 0]], float)
    t2 = np.array([[2, 2], [2, 5], [2, 2]], float)
    assert triangle_dif(t1, t2) == pytest.approx(0.0, abs=1e-15)
    assert triangle_dif(np.zeros((3, 2)), t2) == 1.0


def test_outline_dif_is_the_n_point_triangle_dif() -> None:
    from shapetree.geometry import outline_dif

    rng = np.random.default_rng(3)
    for _ in range(20):
        a, b = rng.normal(size=(3, 2)), rng.normal(size=(3, 2))
        assert outline_dif(a, b) == pytest.approx(float(triangle_dif(a, b)), abs=1e-12)
    pts = rng.normal(size=(12, 2))
    rot = np.array([[0.6, -0.8], [0.8, 0.6]])
    assert outline_dif(pts, 3.0 * pts @ rot.T + [5.0, -2.0]) == pytest.approx(0.0, abs=1e-12)
    assert outline_dif(pts, pts[::-1]) > 0.1  # labels matter
    assert outline_dif(pts, np.ones((12, 2))) == 1.0
    with pytest.raises(ValueError, match="point sets"):
        outline_dif(pts, pts[:5])


# --- the one compiled dif -------------------------------------------------------------


def _exact_dif(a: np.ndarray, b: np.ndarray) -> float:
    """dif of two point sets in exact rational arithmetic (coordinates taken as given)."""
    from fractions import Fraction

    def centred(p):
        pts = [(Fraction(x), Fraction(y)) for x, y in p]
        cx = sum(x for x, _ in pts) / len(pts)
        cy = sum(y for _, y in pts) / len(pts)
        return [(x - cx, y - cy) for x, y in pts]

    z, w = centred(a), centred(b)
    nz = sum(x * x + y * y for x, y in z)
    nw = sum(x * x + y * y for x, y in w)
    # <z, w> = sum conj(z_i) w_i
    re = sum(zx * wx + zy * wy for (zx, zy), (wx, wy) in zip(z, w, strict=True))
    im = sum(zx * wy - zy * wx for (zx, zy), (wx, wy) in zip(z, w, strict=True))
    return float(1 - (re * re + im * im) / (nz * nw))


def test_compiled_dif_equals_the_oracle_and_the_stitching_dif():
    """geometry's public dif, the stitching DP's and the test oracle's literal one agree,
    degenerate triangles included (zero size: DEGENERATE_DIF = 1)."""
    from shapetree.detection._stitch import _dif as stitch_dif
    from shapetree.geometry import DEGENERATE_DIF
    from shapetree.matching._reference import _dif as oracle_dif

    rng = np.random.default_rng(7)
    tris = [rng.normal(size=(3, 2)) for _ in range(30)]
    p = rng.normal(size=2)
    tris += [np.array([p, p, p]), np.array([p, p + 1, p]), np.array([p, p, p + 1])]
    for a in tris:
        for b in tris[::3]:
            want = oracle_dif(a, b)
            assert float(triangle_dif(a, b)) == pytest.approx(want, abs=1e-12)
            za, zb = (t[:, 0] + 1j * t[:, 1] for t in (a, b))
            assert stitch_dif(*za, *zb) == pytest.approx(want, abs=1e-12)
    assert float(triangle_dif(tris[-3], tris[-3])) == DEGENERATE_DIF == 1.0


def test_small_dif_keeps_its_relative_precision():
    """Lagrange's form has no cancellation: a dif of ~1e-20 is right to ~1e-12 relative,
    where 1 - |<z, w>|^2 would give 0 or rounding noise."""
    a = np.array([[0.0, 0.0], [0.5, 0.75], [1.0, 0.0]])
    for eps in (1e-6, 1e-8, 1e-10):
        b = a.copy()
        b[1, 1] += eps
        got = float(triangle_dif(a, b))
        assert got == pytest.approx(_exact_dif(a, b), rel=1e-9)
        assert got > 0
    pts = np.random.default_rng(5).normal(size=(9, 2))
    moved = pts.copy()
    moved[3, 0] += 1e-9
    from shapetree.geometry import outline_dif

    assert outline_dif(pts, moved) == pytest.approx(_exact_dif(pts, moved), rel=1e-6)


def test_procrustes_dif_broadcasts_and_checks_shapes():
    rng = np.random.default_rng(2)
    u = rng.normal(size=(4, 5, 2))
    v = rng.normal(size=2)
    d = procrustes_dif(u, v)
    assert d.shape == (4, 5)
    assert d[1, 2] == pytest.approx(float(procrustes_dif(u[1, 2], v)), abs=1e-15)
    assert np.ndim(procrustes_dif([0.1, 0.2], [0.3, 0.4])) == 0
    with pytest.raises(ValueError, match="length 2"):
        procrustes_dif(np.zeros(3), np.zeros(2))
    with pytest.raises(ValueError, match=r"\(\.\.\., 3, 2\)"):
        triangle_dif(np.zeros((4, 2)), np.zeros((3, 2)))
    tri = rng.normal(size=(6, 3, 2))
    np.testing.assert_allclose(
        triangle_dif(tri, tri[0]), [float(triangle_dif(t, tri[0])) for t in tri], atol=1e-15
    )


def test_geometry_dif_functions_share_the_flags():
    from numba.core.cpu import FastMathOptions

    from shapetree.geometry import _dif
    from shapetree.geometry._dif import FASTMATH

    for name in ("lagrange_form", "unit_helmert", "helmert_dif", "points_dif", "weighted_dif"):
        fn = getattr(_dif, name)
        assert FastMathOptions(fn.targetoptions["fastmath"]).flags == set(FASTMATH)
        assert fn.targetoptions["nogil"] and fn._cache.__class__.__name__ != "NullCache"


# --- the pseudo-hyperbolic dif (issue 15, footnote 2 of the paper) ---------------------


def _upper(rng: np.random.Generator, n: int) -> np.ndarray:
    return np.c_[rng.uniform(-2, 2, n), rng.uniform(0.05, 2, n)]


def test_poincare_distance_is_a_metric_on_the_half_plane():
    from shapetree.geometry import poincare_distance

    rng = np.random.default_rng(15)
    u, v, w = _upper(rng, 400), _upper(rng, 400), _upper(rng, 400)
    duv, dvw, duw = poincare_distance(u, v), poincare_distance(v, w), poincare_distance(u, w)
    assert np.all(duw <= duv + dvw + 1e-12)  # triangle inequality
    np.testing.assert_allclose(duv, poincare_distance(v, u), rtol=0, atol=0)  # symmetric
    assert np.all(poincare_distance(u, u) == 0) and np.all(duv > 0)
    # the closed form on the imaginary axis: d(i a, i b) = |log(b / a)|
    np.testing.assert_allclose(poincare_distance([0, 0.5], [0, 2.0]), np.log(4.0), rtol=1e-12)
    # a lower point is measured as its mirror image; opposite sides / the axis: infinite
    np.testing.assert_allclose(poincare_distance(u * [1, -1], v * [1, -1]), duv, rtol=1e-12)
    assert poincare_distance([0, 1], [0, -1]) == np.inf
    assert poincare_distance([0.3, 0], [0.1, 1]) == np.inf
    assert poincare_distance([0.3, 0], [0.3, 0]) == 0


def _tri_from_bookstein(u: np.ndarray) -> np.ndarray:
    """Triangles (first, middle, last) = ((-1/2, 0), u, (1/2, 0))."""
    t = np.zeros(u.shape[:-1] + (3, 2))
    t[..., 0, 0], t[..., 2, 0] = -0.5, 0.5
    t[..., 1, :] = u
    return t


def test_hyperbolic_dif_is_the_regularised_tanh_squared_of_the_geodesic():
    from shapetree.geometry import hyperbolic_dif, poincare_distance
    from shapetree.geometry._dif import HYPERBOLIC_EPS

    rng = np.random.default_rng(16)
    u, v = _upper(rng, 300), _upper(rng, 300)
    got = hyperbolic_dif(_tri_from_bookstein(u), _tri_from_bookstein(v))
    uc, vc = u[:, 0] + 1j * u[:, 1], v[:, 0] + 1j * v[:, 1]
    gap, mir = np.abs(uc - vc) ** 2, np.abs(uc - vc.conj()) ** 2
    np.testing.assert_allclose(got, np.minimum(gap / (mir + HYPERBOLIC_EPS), 1), rtol=1e-9)
    # without the regularisation the value is tanh(d / 2)^2 of the Poincare geodesic
    np.testing.assert_allclose(gap / mir, np.tanh(poincare_distance(u, v) / 2) ** 2, rtol=1e-9)
    # monotone in the geodesic where the regularisation is negligible (far from the axis)
    far_u, far_v = u + [0, 3], v + [0, 3]
    d = poincare_distance(far_u, far_v)
    h = hyperbolic_dif(_tri_from_bookstein(far_u), _tri_from_bookstein(far_v))
    order = np.argsort(d)
    assert np.all(np.diff(h[order]) > -1e-3)


@settings(max_examples=40, deadline=None)
@given(st.lists(coords, min_size=12, max_size=12), coords, st.floats(0.1, 10), coords, coords)
def test_hyperbolic_dif_invariance_symmetry_and_zero(xs, angle, scale, tx, ty):
    from shapetree.geometry import hyperbolic_dif

    ta, tb = np.array(xs[:6]).reshape(3, 2), np.array(xs[6:]).reshape(3, 2)
    for t in (ta, tb):
        if np.hypot(*(t[2] - t[0])) < 1e-2 or np.hypot(*(t[1] - t[0])) < 1e-2:
            return
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    sa = scale * ta @ rot.T + [tx, ty]
    d = float(hyperbolic_dif(ta, tb))
    assert 0 <= d <= 1
    assert abs(float(hyperbolic_dif(sa, tb)) - d) < 1e-6  # similarity invariant
    assert abs(float(hyperbolic_dif(tb, ta)) - d) < 1e-9  # symmetric
    assert float(hyperbolic_dif(ta, sa)) < 1e-9  # equal triangles (up to a similarity)


def test_hyperbolic_dif_degenerate_rules():
    from shapetree.geometry import DEGENERATE_DIF, hyperbolic_dif
    from shapetree.geometry._dif import HYPERBOLIC_EPS

    up = np.array([[0, 0], [0.5, 0.4], [1, 0]], float)
    down = up * [1, -1]  # the mirror image: opposite orientation
    flat = np.array([[0, 0], [0.5, 0], [1, 0]], float)
    flat2 = np.array([[0, 0], [0.8, 0], [1, 0]], float)
    point = np.zeros((3, 2))
    needle = np.array([[0, 0], [1, 1], [0, 0]], float)
    needle2 = np.array([[2, 0], [5, -1], [2, 0]], float)
    assert hyperbolic_dif(up, down) == 1.0  # mirror images
    assert hyperbolic_dif(flat, flat * 3 + 1) == 0.0  # the same collinear shape
    # collinear vs collinear: |u - v|^2 / (|u - v|^2 + eps); u = 0, v = 0.3
    np.testing.assert_allclose(hyperbolic_dif(flat, flat2), 0.09 / (0.09 + HYPERBOLIC_EPS))
    assert 0 < hyperbolic_dif(flat, up) < 1
    assert hyperbolic_dif(point, point) == DEGENERATE_DIF == hyperbolic_dif(point, up)
    assert hyperbolic_dif(needle, needle2) == 0.0 and hyperbolic_dif(needle, up) == 1.0
