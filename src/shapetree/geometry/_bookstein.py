"""Bookstein coordinates and the squared Procrustes distance between triangles (paper §2.1, §3).

Points in the plane are handled as complex numbers ``x + iy`` internally; the public
functions take and return ``(..., 2)`` float arrays.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def _as_complex(p: ArrayLike) -> np.ndarray:
    a = np.asarray(p, dtype=float)
    if a.shape[-1:] != (2,):
        raise ValueError(f"expected points with a last axis of length 2, got shape {a.shape}")
    return a[..., 0] + 1j * a[..., 1]


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

    The triangles are ``(-0.5, 0), (0.5, 0), u`` and ``(-0.5, 0), (0.5, 0), v``, i.e. the
    triangles ``(a_1, a_n, a_i)`` and ``(b_1, b_m, b_j)`` of eq. (1). With both triangles
    centred and scaled to unit size, ``dif = 1 - |<z, w>|^2``: 0 for similar triangles,
    at most 1. Reflections are *not* factored out.

    Parameters
    ----------
    u, v : array_like, shape (..., 2)

    Returns
    -------
    ndarray, shape (...)
    """
    zu, zv = _as_complex(u), _as_complex(v)
    num = np.abs(0.5 + (2.0 / 3.0) * np.conj(zu) * zv) ** 2
    den = (0.5 + (2.0 / 3.0) * np.abs(zu) ** 2) * (0.5 + (2.0 / 3.0) * np.abs(zv) ** 2)
    return np.maximum(1.0 - num / den, 0.0)


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
    whose three points coincide is at distance 1 from everything.

    Parameters
    ----------
    tri_a, tri_b : array_like, shape (..., 3, 2)
        Triangles as ``(first, middle, last)`` points.

    Returns
    -------
    ndarray, shape (...)
        Values in ``[0, 1]``.
    """
    ha, hb = helmert(tri_a), helmert(tri_b)
    ip = np.sum(np.conj(ha) * hb, axis=-1)
    return np.clip(1.0 - np.abs(ip) ** 2, 0.0, 1.0)


def outline_dif(points_a: ArrayLike, points_b: ArrayLike) -> float:
    """Squared full Procrustes distance between two labelled point sets, in ``[0, 1]``.

    The ``n``-point form of :func:`triangle_dif`: ``1 - |<z, w>|^2`` with ``z``, ``w``
    the centred, unit-size complex coordinates. 0 when one set is a similarity transform
    of the other; a set whose points all coincide is at distance 1 from everything.

    Parameters
    ----------
    points_a, points_b : array_like, shape (n, 2)
        Corresponding points (row ``i`` of one matches row ``i`` of the other).

    Returns
    -------
    float
    """
    z, w = _as_complex(points_a), _as_complex(points_b)
    if z.shape != w.shape or z.ndim != 1:
        raise ValueError(f"expected two (n, 2) point sets, got shapes {z.shape} and {w.shape}")
    z, w = z - z.mean(), w - w.mean()
    nz, nw = np.linalg.norm(z), np.linalg.norm(w)
    if nz == 0 or nw == 0:
        return 1.0
    return float(np.clip(1.0 - abs(np.vdot(z, w)) ** 2 / (nz * nw) ** 2, 0.0, 1.0))
