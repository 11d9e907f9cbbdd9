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

Hyperbolic ``dif`` (paper, footnote 2)
--------------------------------------
The Bookstein coordinate ``u`` of a triangle's middle point (:func:`~shapetree.geometry.
bookstein`, with the base ``first -> last``) is a point of the plane; for triangles of the
same orientation (``Im u``, ``Im v`` of one sign) the natural deformation measure is the
geodesic distance of the Poincaré half-plane, ``d(u, v) = arcosh(1 + |u - v|^2 / (2 Im u
Im v))`` (the log of the anisotropy of the affine map between the two triangles). The
matching option ``dif="hyperbolic"`` starts from the **pseudo-hyperbolic** distance
squared, ``tanh^2(d / 2) = |u - v|^2 / |u - conj(v)|^2``, a monotone function of ``d``
bounded by 1 like the Procrustes ``dif``, and regularises it near the real axis:

    hdif(u, v) = |u - v|^2 / (|u - conj(v)|^2 + eps),   clipped to [0, 1],

with :data:`HYPERBOLIC_EPS` ``eps = 0.01``. Without ``eps`` the value is ill-conditioned
at the boundary of the half-plane: a straight stretch of a curve gives triangles with
``Im u`` at rounding level, and two such triangles (a shape against itself) would differ
by an arbitrary amount in ``[0, 1]``. With ``eps`` triangles whose middle point is much
closer than ``sqrt(eps) / 2 = 5%`` of the base length to the base line are compared like
the Procrustes ``dif`` (``~ |u - v|^2 / eps``), curved ones hyperbolically. In Helmert
coordinates (``u = (sqrt 3 / 2) z2 / z1``) ``|u - v|^2`` is ``(4 / 3) / (a1 b1)^2`` times
the Procrustes Lagrange form ``|a1 b2 - a2 b1|^2`` and ``|u - conj v|^2`` the same factor
times the form against the *mirror image* of the second triangle (``b2`` conjugated), so

    hdif = |a1 b2 - a2 b1|^2 / (|a1 conj(b2) - a2 b1|^2 + (4 eps / 3) (a1 b1)^2):

two Lagrange forms and one division (:func:`hyperbolic_form`), defined for every triangle
with no Bookstein singularity. Its rules:

* orientation matters: ``Im u`` and ``Im v`` of opposite signs (a triangle against a
  mirror-image shape) give ``|u - v| >= |u - conj v|``: close to or clipped to **1** (no
  orientation-preserving deformation joins them without passing through a collinear
  triangle, the boundary of the half-plane);
* a collinear triangle (middle point on the line of the base, ``Im u = 0``) against
  another collinear one costs ``|u - v|^2 / (|u - v|^2 + eps)`` (0 for the same one);
* a "needle" (``first == last``, ``u = infinity``, all such triangles have one shape):
  0 against a needle, 1 against anything else;
* a triangle of zero size (three coincident points): :data:`DEGENERATE_DIF` ``= 1``
  against everything, as for the Procrustes ``dif``.

The geodesic itself (unbounded, for points of the upper half-plane) is
:func:`~shapetree.geometry.poincare_distance`.

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

from shapetree._numba_cache import install as _install_cache_locators

# before the first njit below: every kernel module imports this one first, so every
# cached shapetree kernel notices an edit of any kernel source (shapetree._numba_cache)
_install_cache_locators()

#: LLVM fast-math flags of every compiled kernel of the project: fast-math without
#: ``nnan`` / ``ninf`` (no assumption that NaN or infinity never occur). Pass it as
#: ``fastmath=set(FASTMATH)`` (numba takes a ``set``).
FASTMATH = frozenset({"nsz", "arcp", "contract", "afn", "reassoc"})

#: ``dif`` of a point set of zero size (all points coincide) against anything.
DEGENERATE_DIF = 1.0

#: Regularisation ``eps`` of the pseudo-hyperbolic ``dif`` near the real axis (module
#: docstring): ``hdif = |u - v|^2 / (|u - conj v|^2 + eps)`` for Bookstein coordinates.
HYPERBOLIC_EPS = 0.01

#: ``eps`` in the units of the Helmert Lagrange forms (``4 eps / 3``).
_HYP_EPS_H = HYPERBOLIC_EPS * 4.0 / 3.0

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
def hyperbolic_ratio(num: float, den: float) -> float:
    """``num / den`` clipped to ``[0, 1]``, from the two Lagrange forms of the
    pseudo-hyperbolic ``dif`` (module docstring): ``1`` when ``num >= den > 0`` or ``den
    == 0 < num`` (opposite orientations, a collinear triangle against another shape), ``0``
    when ``num == 0`` (the same shape, collinear or needle)."""
    if num < den:
        return num / den
    return 1.0 if num > 0.0 else 0.0


@_jit
def hyperbolic_den(a1: float, a2r: float, a2i: float, b1: float, b2r: float, b2i: float) -> float:
    """Denominator of the regularised pseudo-hyperbolic ``dif`` in Helmert coordinates:
    ``|a1 conj(b2) - a2 b1|^2 + (4 eps / 3) (a1 b1)^2`` (module docstring)."""
    p = a1 * b1
    return lagrange_form(a1, a2r, a2i, b1, b2r, -b2i) + _HYP_EPS_H * (p * p)


@_jit
def hyperbolic_form(a1: float, a2r: float, a2i: float, b1: float, b2r: float, b2i: float) -> float:
    """Regularised pseudo-hyperbolic ``dif`` of two non-degenerate triangles in
    :func:`unit_helmert` coordinates, clipped to ``[0, 1]`` (module docstring). Scaling the
    first triple by ``sqrt(λ)`` scales numerator and denominator alike."""
    num = lagrange_form(a1, a2r, a2i, b1, b2r, b2i)
    return hyperbolic_ratio(num, hyperbolic_den(a1, a2r, a2i, b1, b2r, b2i))


@_jit
def helmert_dif_kind(
    a1: float, a2r: float, a2i: float, b1: float, b2r: float, b2i: float, hyper: bool
) -> float:
    """:func:`helmert_dif` (``hyper`` false) or the pseudo-hyperbolic ``dif`` (true)."""
    if not hyper:
        return helmert_dif(a1, a2r, a2i, b1, b2r, b2i)
    if is_zero_shape(a1, a2r, a2i) or is_zero_shape(b1, b2r, b2i):
        return DEGENERATE_DIF
    return hyperbolic_form(a1, a2r, a2i, b1, b2r, b2i)


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
def weighted_dif_kind(
    lam: float,
    q1: float,
    q2r: float,
    q2i: float,
    z1: float,
    z2r: float,
    z2i: float,
    hyper: bool,
) -> float:
    """:func:`weighted_dif` (``hyper`` false) or ``λ`` times the pseudo-hyperbolic ``dif``."""
    if not hyper:
        return weighted_dif(lam, q1, q2r, q2i, z1, z2r, z2i)
    if is_zero_shape(z1, z2r, z2i):
        return lam * DEGENERATE_DIF
    return lam * hyperbolic_form(q1, q2r, q2i, z1, z2r, z2i)


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
    hyper: bool = False,
) -> float:
    """``dif`` of triangles ``a`` and ``b``, each given as ``(first, middle, last)``
    (``hyper``: the pseudo-hyperbolic ``dif``)."""
    a1, a2r, a2i = unit_helmert(ax1, ay1, ax2, ay2, ax3, ay3)
    b1, b2r, b2i = unit_helmert(bx1, by1, bx2, by2, bx3, by3)
    return helmert_dif_kind(a1, a2r, a2i, b1, b2r, b2i, hyper)


@_jit
def triangle_dif_many(a: np.ndarray, b: np.ndarray, out: np.ndarray, hyper: bool = False) -> None:
    """``out[i] = dif(a[i], b[i])`` for triangles ``a``, ``b`` of shape ``(N, 3, 2)``
    (``hyper``: the pseudo-hyperbolic ``dif``)."""
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
            hyper,
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
    hyper: bool = False,
) -> None:
    """``out[i] = weighted_dif_kind(lam, q1, q2r, q2i, z1[i], z2r[i], z2i[i], hyper)``."""
    for i in range(out.shape[0]):
        out[i] = weighted_dif_kind(lam, q1, q2r, q2i, z1[i], z2r[i], z2i[i], hyper)


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
    "HYPERBOLIC_EPS",
    "helmert_dif",
    "helmert_dif_kind",
    "hyperbolic_den",
    "hyperbolic_form",
    "hyperbolic_ratio",
    "is_zero_shape",
    "lagrange_form",
    "points_dif",
    "triangle_dif_many",
    "triangle_dif_xy",
    "unit_helmert",
    "unit_helmert_many",
    "weighted_dif",
    "weighted_dif_kind",
    "weighted_dif_many",
]


# --- plain-IEEE twin for the symmetric matcher ---------------------------------------
# The symmetric matcher (matching._subcurves) needs dif(a, b) == dif(b, a) *bitwise*.
# Under the fast-math flag "contract" LLVM may fuse ``a1 * b2 - a2 * b1`` into an FMA,
# whose rounding depends on which product is fused, so the swapped call can differ in
# the last bit. These twins compute the same values with no fast-math flags: products
# commute exactly and ``x - y == -(y - x)`` in IEEE arithmetic, so swapping the
# arguments gives the same float. Not in ``__all__`` (every name there is compiled with
# :data:`FASTMATH`).

_jit_ieee = njit(cache=True, nogil=True)


@_jit_ieee
def _ieee_lagrange(a1: float, a2r: float, a2i: float, b1: float, b2r: float, b2i: float) -> float:
    wr = a1 * b2r - a2r * b1
    wi = a1 * b2i - a2i * b1
    return wr * wr + wi * wi


@_jit_ieee
def exact_dif_kind(
    a1: float, a2r: float, a2i: float, b1: float, b2r: float, b2i: float, hyper: bool
) -> float:
    """:func:`helmert_dif_kind` without fast-math: bitwise symmetric in its two triangles."""
    if is_zero_shape(a1, a2r, a2i) or is_zero_shape(b1, b2r, b2i):
        return DEGENERATE_DIF
    num = _ieee_lagrange(a1, a2r, a2i, b1, b2r, b2i)
    if not hyper:
        return num if num < 1.0 else 1.0
    p = a1 * b1
    den = _ieee_lagrange(a1, a2r, a2i, b1, b2r, -b2i) + _HYP_EPS_H * (p * p)
    if num < den:
        return num / den
    return 1.0 if num > 0.0 else 0.0
