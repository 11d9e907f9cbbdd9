"""Bookstein coordinates and the squared Procrustes distance between triangles (paper §2.1, §3).

Points in the plane are handled as complex numbers ``x + iy`` internally; the public
functions take and return ``(..., 2)`` float arrays. The ``dif`` functions are thin
wrappers around the one compiled implementation in :mod:`shapetree.geometry._dif`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from shapetree._errors import ShapeTreeError
from shapetree.geometry._dif import points_dif, triangle_dif_many


def _as_complex(p: ArrayLike) -> np.ndarray:
    a = np.asarray(p, dtype=float)
    if a.shape[-1:] != (2,):
        raise ValueError(f"expected points with a last axis of length 2, got shape {a.shape}")
    return a[..., 0] + 1j * a[..., 1]


def _as_points(p: ArrayLike) -> np.ndarray:
    a = np.asarray(p, dtype=float)
    if a.shape[-1:] != (2,):
        raise ValueError(f"expected points with a last axis of length 2, got shape {a.shape}")
    return a


def _triangle_dif(ta: np.ndarray, tb: np.ndarray, hyper: bool = False) -> np.ndarray:
    """Broadcast two ``(..., 3, 2)`` triangle arrays and call the compiled ``dif``."""
    ta, tb = np.broadcast_arrays(ta, tb)
    shape = ta.shape[:-2]
    a = np.ascontiguousarray(ta.reshape(-1, 3, 2))
    b = np.ascontiguousarray(tb.reshape(-1, 3, 2))
    out = np.empty(a.shape[0])
    triangle_dif_many(a, b, out, bool(hyper))
    return out.reshape(shape)[()]


def _as_xy(z: np.ndarray) -> np.ndarray:
    return np.stack([z.real, z.imag], axis=-1)


def bookstein(p1: ArrayLike, p2: ArrayLike, p3: ArrayLike) -> np.ndarray:
    """Bookstein coordinate of ``p3`` with respect to ``p1`` and ``p2``.

    The unique similarity transform that maps ``p1`` to ``(-0.5, 0)`` and ``p2`` to
    ``(0.5, 0)`` maps ``p3`` to its Bookstein coordinate (paper §2.1).

    Parameters
    ----------
    p1, p2, p3 : array_like, shape (..., 2)
        Points (broadcast together). ``p1`` and ``p2`` must differ.

    Returns
    -------
    ndarray, shape (..., 2)
        The Bookstein coordinate ``(u, v)``; dimensionless.
    """
    z1, z2, z3 = _as_complex(p1), _as_complex(p2), _as_complex(p3)
    d = z2 - z1
    if np.any(d == 0):
        raise ValueError("Bookstein coordinates need two distinct base points (p1 == p2)")
    return _as_xy((z3 - 0.5 * (z1 + z2)) / d)


def from_bookstein(p1: ArrayLike, p2: ArrayLike, u: ArrayLike) -> np.ndarray:
    """Place a point from its Bookstein coordinate ``u`` relative to ``p1`` and ``p2``.

    Inverse of :func:`bookstein`: ``from_bookstein(p1, p2, bookstein(p1, p2, p3)) == p3``.

    Parameters
    ----------
    p1, p2 : array_like, shape (..., 2)
        Base points.
    u : array_like, shape (..., 2)
        Bookstein coordinate.

    Returns
    -------
    ndarray, shape (..., 2)
    """
    z1, z2, w = _as_complex(p1), _as_complex(p2), _as_complex(u)
    return _as_xy(0.5 * (z1 + z2) + w * (z2 - z1))


def procrustes_dif(u: ArrayLike, v: ArrayLike) -> np.ndarray:
    """Squared full Procrustes distance between two triangles given by Bookstein coordinates.

    The triangles are ``(-0.5, 0), u, (0.5, 0)`` and ``(-0.5, 0), v, (0.5, 0)``, i.e. the
    triangles ``(a_1, a_i, a_n)`` and ``(b_1, b_j, b_m)`` of eq. (1). With both triangles
    centred and scaled to unit size, ``dif = 1 - |<z, w>|^2``: 0 for similar triangles,
    at most 1. Reflections are *not* factored out. Computed by the one compiled ``dif``
    (:mod:`shapetree.geometry._dif`).

    Parameters
    ----------
    u, v : array_like, shape (..., 2)

    Returns
    -------
    ndarray, shape (...)
    """
    uu, vv = np.broadcast_arrays(_as_points(u), _as_points(v))
    shape = uu.shape[:-1]
    base = np.zeros(shape + (3, 2))
    base[..., 0, 0], base[..., 2, 0] = -0.5, 0.5
    ta, tb = base.copy(), base
    ta[..., 1, :], tb[..., 1, :] = uu, vv
    return _triangle_dif(ta, tb)


def helmert(tri: ArrayLike) -> np.ndarray:
    """Unit-size Helmert coordinates of triangles ``(first, middle, last)``.

    Returns the pair ``(h1, h2)`` of complex numbers with ``h1 = (last - first)/sqrt(2)``,
    ``h2 = (2 middle - first - last)/sqrt(6)``, scaled so ``|h1|^2 + |h2|^2 = 1`` (all zero
    for a triangle whose three points coincide).

    Parameters
    ----------
    tri : array_like, shape (..., 3, 2)

    Returns
    -------
    ndarray of complex, shape (..., 2)
    """
    z = _as_complex(tri)
    first, mid, last = z[..., 0], z[..., 1], z[..., 2]
    h = np.stack([(last - first) / np.sqrt(2.0), (2 * mid - first - last) / np.sqrt(6.0)], -1)
    norm = np.sqrt(np.sum(np.abs(h) ** 2, axis=-1, keepdims=True))
    return np.divide(h, norm, out=np.zeros_like(h), where=norm > 0)


def triangle_dif(tri_a: ArrayLike, tri_b: ArrayLike) -> np.ndarray:
    """Squared full Procrustes distance between triangles ``(first, middle, last)``.

    Equals :func:`procrustes_dif` of the middles' Bookstein coordinates, but is defined
    for every triangle: when ``first == last`` it still compares shapes, and a triangle
    whose three points coincide has no shape: it is at distance
    :data:`~shapetree.geometry.DEGENERATE_DIF` ``= 1`` from everything (itself included).
    Computed by the one compiled ``dif`` (:mod:`shapetree.geometry._dif`).

    Parameters
    ----------
    tri_a, tri_b : array_like, shape (..., 3, 2)
        Triangles as ``(first, middle, last)`` points (broadcast together).

    Returns
    -------
    ndarray, shape (...)
        Values in ``[0, 1]``.
    """
    ta, tb = np.asarray(tri_a, dtype=float), np.asarray(tri_b, dtype=float)
    for t in (ta, tb):
        if t.shape[-2:] != (3, 2):
            raise ValueError(f"expected triangles of shape (..., 3, 2), got shape {t.shape}")
    return _triangle_dif(ta, tb)


def hyperbolic_dif(tri_a: ArrayLike, tri_b: ArrayLike) -> np.ndarray:
    """Pseudo-hyperbolic ``dif`` of triangles ``(first, middle, last)`` (paper, footnote 2).

    With ``u``, ``v`` the Bookstein coordinates of the middle points (base ``first ->
    last``), ``tanh^2(d / 2) = |u - v|^2 / |u - conj v|^2`` clipped to ``[0, 1]``, where
    ``d`` is :func:`poincare_distance`. It is the ``dif`` of the matching option
    ``dif="hyperbolic"``, computed by the one compiled implementation
    (:mod:`shapetree.geometry._dif`, whose docstring states the rules): 0 for similar
    triangles; 1 for triangles of opposite orientation, for a collinear triangle against
    any other shape, and (:data:`~shapetree.geometry.DEGENERATE_DIF`) for a triangle whose
    three points coincide.

    Parameters
    ----------
    tri_a, tri_b : array_like, shape (..., 3, 2)
        Triangles as ``(first, middle, last)`` points (broadcast together).

    Returns
    -------
    ndarray, shape (...)
        Values in ``[0, 1]``.
    """
    ta, tb = np.asarray(tri_a, dtype=float), np.asarray(tri_b, dtype=float)
    for t in (ta, tb):
        if t.shape[-2:] != (3, 2):
            raise ShapeTreeError(f"expected triangles of shape (..., 3, 2), got shape {t.shape}")
    return _triangle_dif(ta, tb, hyper=True)


def poincare_distance(u: ArrayLike, v: ArrayLike) -> np.ndarray:
    """Geodesic distance of the Poincaré half-plane between Bookstein coordinates.

    ``d(u, v) = arcosh(1 + |u - v|^2 / (2 Im u Im v))`` for points on the same side of the
    real axis (a point of the lower half-plane is measured as its mirror image, so ``d(u,
    v) = d(conj u, conj v)``); ``inf`` for points on opposite sides or on the axis
    (collinear triangles lie on the boundary, infinitely far), except ``0`` for ``u ==
    v``. :func:`hyperbolic_dif` is ``tanh(d / 2) ** 2``.

    Parameters
    ----------
    u, v : array_like, shape (..., 2)
        Bookstein coordinates (broadcast together).

    Returns
    -------
    ndarray, shape (...)
    """
    uu, vv = np.broadcast_arrays(_as_complex(u), _as_complex(v))
    prod = uu.imag * vv.imag
    gap = np.abs(uu - vv) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        arg = 1.0 + gap / (2.0 * np.where(prod > 0, prod, 1.0))
        d = np.where(prod > 0, np.arccosh(np.maximum(arg, 1.0)), np.inf)
    return np.where(gap == 0, 0.0, d)[()]


def outline_dif(points_a: ArrayLike, points_b: ArrayLike) -> float:
    """Squared full Procrustes distance between two labelled point sets, in ``[0, 1]``.

    The ``n``-point form of :func:`triangle_dif`: ``1 - |<z, w>|^2`` with ``z``, ``w``
    the centred, unit-size complex coordinates. 0 when one set is a similarity transform
    of the other; a set whose points all coincide has no shape and is at distance
    :data:`~shapetree.geometry.DEGENERATE_DIF` ``= 1`` from everything. Computed by the
    one compiled ``dif`` (:mod:`shapetree.geometry._dif`).

    Parameters
    ----------
    points_a, points_b : array_like, shape (n, 2)
        Corresponding points (row ``i`` of one matches row ``i`` of the other).

    Returns
    -------
    float
    """
    a, b = _as_points(points_a), _as_points(points_b)
    if a.shape != b.shape or a.ndim != 2:
        raise ValueError(
            f"expected two (n, 2) point sets, got shapes {a.shape[:-1]} and {b.shape[:-1]}"
        )
    a, b = np.ascontiguousarray(a.T), np.ascontiguousarray(b.T)
    return float(points_dif(a[0], a[1], b[0], b[1]))
