"""The one compiled implementation of ``dif``, the squared full Procrustes distance.

Every ``dif`` of the project is computed here: the matching kernel's target tables and
its inner loop (:mod:`shapetree.matching._kernels`), the model constants and the
traceback (:mod:`shapetree.matching._prepare`, :mod:`shapetree.matching._match`), the
stitching DP (:mod:`shapetree.detection._stitch`) and the public functions of
:mod:`shapetree.geometry` (:func:`~shapetree.geometry.procrustes_dif`,
:func:`~shapetree.geometry.triangle_dif`, :func:`~shapetree.geometry.outline_dif`). Only
the test oracle (:mod:`shapetree.matching._reference`) keeps a separate, literal
pure-Python ``dif``, on purpose.

Definition
----------
Two labelled point sets (triangles ``(first, middle, last)`` in eq. (1)) are centred and
scaled to unit size, as complex vectors ``z`` and ``w``; then

    dif = 1 - |<z, w>|^2,

0 for similar sets (one a rotation, scaling and translation of the other), at most 1.
Reflections are not factored out. A triangle is kept as its unit-size Helmert
coordinates ``(h1, h2)`` (``h1 = (last - first) / sqrt 2``, ``h2 = (2 middle - first -
last) / sqrt 6``, divided by ``sqrt(|h1|^2 + |h2|^2)``), rotated so that ``h1`` is real
and ``>= 0``; by Lagrange's identity for unit vectors of ``C^2``

    dif = |a1 b2 - a2 b1|^2,

a sum of two squares with no cancellation (small ``dif`` keep their relative precision,
in float32 too). For ``n`` points the same identity reads ``dif = sum_{i<j} |z_i w_j -
z_j w_i|^2`` for the centred, unit-size vectors.

Degenerate sets (the one rule)
------------------------------
A triangle (or point set) whose points all coincide has **zero size and no shape**: its
``dif`` against any set, itself included, is :data:`DEGENERATE_DIF` ``= 1``, the maximum
of the squared full Procrustes distance (it is "as far from every shape as possible";
nothing is gained by deforming a subcurve onto a single point). Zero size is tested
exactly (Helmert coordinates of coincident points are exactly zero); a triangle whose
first and last points coincide but whose middle differs is *not* degenerate: it has a
shape (a "needle" out and back) and is compared as usual. Its Helmert coordinates
``(0, h2)`` carry no rotation reference for ``h1``; ``h2`` is kept as it is.

Compilation
-----------
All functions are ``numba.njit(cache=True, nogil=True)`` with the explicit fast-math
flag set :data:`FASTMATH`, which leaves out ``nnan`` and ``ninf`` (callers compare
against large sentinels and may see ``inf``; LLVM must not assume they never occur).
Note that numba's on-disk cache of a kernel that calls these functions is keyed on the
*kernel's* source file only: after editing this module, delete the ``*.nbi`` / ``*.nbc``
files under ``src/shapetree/matching/__pycache__`` and ``src/shapetree/detection/
__pycache__`` (or touch the kernel modules).
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: LLVM fast-math flags of every compiled kernel of the project: fast-math without
#: ``nnan`` / ``ninf`` (no assumption that NaN or infinity never occur). Pass it as
#: ``fastmath=set(FASTMATH)`` (numba takes a ``set``).
FASTMATH = frozenset({"nsz", "arcp", "contract", "afn", "reassoc"})

#: ``dif`` of a point set of zero size (all points coincide) against anything.
DEGENERATE_DIF = 1.0

_INV_SQRT2 = 1.0 / np.sqrt(2.0)
_INV_SQRT6 = 1.0 / np.sqrt(6.0)

_jit = njit(cache=True, nogil=True, fastmath=set(FASTMATH))


@_jit
def lagrange_form(a1: float, a2r: float, a2i: float, b1: float, b2r: float, b2i: float) -> float:
    """``|a1 b2 - a2 b1|^2`` for real ``a1``, ``b1`` and complex ``a2``, ``b2``.

    With unit-size, rotated Helmert coordinates this is ``dif`` (see the module
    docstring); with the first pair scaled by ``sqrt(λ)`` it is ``λ dif`` (the matching
    kernel's inner loop). It computes in the precision of its arguments.
    """
    wr = a1 * b2r - a2r * b1
    wi = a1 * b2i - a2i * b1
    return wr * wr + wi * wi


@_jit
def unit_helmert(
    x1: float, y1: float, x2: float, y2: float, x3: float, y3: float
) -> tuple[float, float, float]:
    """Unit-size Helmert coordinates of the triangle ``(first, middle, last)``, rotated.

    Returns
    -------
    z1, z2r, z2i : float
        ``z1 = |h1| / N >= 0`` (real), ``z2 = h2 conj(h1) / (|h1| N)`` with ``N^2 = |h1|^2
        + |h2|^2`` (``z2 = h2 / N`` when ``first == last``); ``(0, 0, 0)`` for a triangle
        of zero size (see :data:`DEGENERATE_DIF`).
    """
    h1r = (x3 - x1) * _INV_SQRT2
    h1i = (y3 - y1) * _INV_SQRT2
    h2r = (2.0 * x2 - x1 - x3) * _INV_SQRT6
    h2i = (2.0 * y2 - y1 - y3) * _INV_SQRT6
    n1 = h1r * h1r + h1i * h1i
    den = n1 + h2r * h2r + h2i * h2i
    if den > 0.0:
        inv = 1.0 / np.sqrt(den)
        if n1 > 0.0:
            a = np.sqrt(n1)
            inv2 = inv / a
            return a * inv, (h2r * h1r + h2i * h1i) * inv2, (h2i * h1r - h2r * h1i) * inv2
        return 0.0, h2r * inv, h2i * inv
    return 0.0, 0.0, 0.0


@_jit
def is_zero_shape(z1: float, z2r: float, z2i: float) -> bool:
    """Whether unit Helmert coordinates are those of a zero-size triangle (all zero)."""
    return z1 == 0.0 and z2r == 0.0 and z2i == 0.0


@_jit
def helmert_dif(a1: float, a2r: float, a2i: float, b1: float, b2r: float, b2i: float) -> float:
    """``dif`` of two triangles given by :func:`unit_helmert` coordinates, in ``[0, 1]``."""
    if is_zero_shape(a1, a2r, a2i) or is_zero_shape(b1, b2r, b2i):
        return DEGENERATE_DIF
    d = lagrange_form(a1, a2r, a2i, b1, b2r, b2i)
    return d if d < 1.0 else 1.0


@_jit
def weighted_dif(
    lam: float, q1: float, q2r: float, q2i: float, z1: float, z2r: float, z2i: float
) -> float:
    """``λ dif`` from the model triangle's coordinates scaled by ``sqrt(λ)`` (``q``) and the
    target triangle's unit coordinates ``z`` (the matching kernel's form; the model
    triangle is never degenerate, a zero-size target triangle costs ``λ``)."""
    if is_zero_shape(z1, z2r, z2i):
        return lam * DEGENERATE_DIF
    return lagrange_form(q1, q2r, q2i, z1, z2r, z2i)


@_jit
def triangle_dif_xy(
    ax1: float,
    ay1: float,
    ax2: float,
    ay2: float,
    ax3: float,
    ay3: float,
    bx1: float,
    by1: float,
    bx2: float,
    by2: float,
    bx3: float,
    by3: float,
) -> float:
    """``dif`` of triangles ``a`` and ``b``, each given as ``(first, middle, last)``."""
    a1, a2r, a2i = unit_helmert(ax1, ay1, ax2, ay2, ax3, ay3)
    b1, b2r, b2i = unit_helmert(bx1, by1, bx2, by2, bx3, by3)
    return helmert_dif(a1, a2r, a2i, b1, b2r, b2i)


@_jit
def triangle_dif_many(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """``out[i] = dif(a[i], b[i])`` for triangles ``a``, ``b`` of shape ``(N, 3, 2)``."""
    for i in range(out.shape[0]):
        out[i] = triangle_dif_xy(
            a[i, 0, 0],
            a[i, 0, 1],
            a[i, 1, 0],
            a[i, 1, 1],
            a[i, 2, 0],
            a[i, 2, 1],
            b[i, 0, 0],
            b[i, 0, 1],
            b[i, 1, 0],
            b[i, 1, 1],
            b[i, 2, 0],
            b[i, 2, 1],
        )


@_jit
def unit_helmert_many(tri: np.ndarray, out: np.ndarray) -> None:
    """``out[i] = unit_helmert(tri[i])`` for triangles of shape ``(N, 3, 2)``; out ``(N, 3)``."""
    for i in range(out.shape[0]):
        z1, z2r, z2i = unit_helmert(
            tri[i, 0, 0], tri[i, 0, 1], tri[i, 1, 0], tri[i, 1, 1], tri[i, 2, 0], tri[i, 2, 1]
        )
        out[i, 0] = z1
        out[i, 1] = z2r
        out[i, 2] = z2i


@_jit
def weighted_dif_many(
    lam: float,
    q1: float,
    q2r: float,
    q2i: float,
    z1: np.ndarray,
    z2r: np.ndarray,
    z2i: np.ndarray,
    out: np.ndarray,
) -> None:
    """``out[i] = weighted_dif(lam, q1, q2r, q2i, z1[i], z2r[i], z2i[i])``."""
    for i in range(out.shape[0]):
        out[i] = weighted_dif(lam, q1, q2r, q2i, z1[i], z2r[i], z2i[i])


@_jit
def points_dif(ax: np.ndarray, ay: np.ndarray, bx: np.ndarray, by: np.ndarray) -> float:
    """``dif`` of two labelled point sets of ``n`` points (coordinate arrays), in ``[0, 1]``.

    Centred, then ``sum_{i<j} |z_i w_j - z_j w_i|^2 / (|z|^2 |w|^2)`` (Lagrange's identity;
    for ``n = 3`` the value of :func:`triangle_dif_xy`). A set whose points all coincide
    has zero size: :data:`DEGENERATE_DIF`.
    """
    n = ax.shape[0]
    deg_a = True
    deg_b = True
    for i in range(1, n):
        if ax[i] != ax[0] or ay[i] != ay[0]:
            deg_a = False
        if bx[i] != bx[0] or by[i] != by[0]:
            deg_b = False
    if deg_a or deg_b:
        return DEGENERATE_DIF
    zr = ax - ax.mean()
    zi = ay - ay.mean()
    wr = bx - bx.mean()
    wi = by - by.mean()
    na = 0.0
    nb = 0.0
    for i in range(n):
        na += zr[i] * zr[i] + zi[i] * zi[i]
        nb += wr[i] * wr[i] + wi[i] * wi[i]
    acc = 0.0
    for i in range(n):
        for j in range(i + 1, n):
            # z_i w_j - z_j w_i
            cr = (zr[i] * wr[j] - zi[i] * wi[j]) - (zr[j] * wr[i] - zi[j] * wi[i])
            ci = (zr[i] * wi[j] + zi[i] * wr[j]) - (zr[j] * wi[i] + zi[j] * wr[i])
            acc += cr * cr + ci * ci
    d = acc / (na * nb)
    return d if d < 1.0 else 1.0


__all__ = [
    "DEGENERATE_DIF",
    "FASTMATH",
    "helmert_dif",
    "is_zero_shape",
    "lagrange_form",
    "points_dif",
    "triangle_dif_many",
    "triangle_dif_xy",
    "unit_helmert",
    "unit_helmert_many",
    "weighted_dif",
    "weighted_dif_many",
]
