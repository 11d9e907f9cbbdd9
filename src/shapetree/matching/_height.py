"""Height functions: a second distance between closed outlines, fused with ψ (not in the paper).

The shape-tree cost ψ compares each triangle of A with its image in B after the triangle's
own alignment. The height functions of Wang, Bai, You, Liu & Latecki (*Shape matching and
classification using height functions*, Pattern Recognition Letters 33, 2012) describe each
sample point instead by the signed distances of all the other points to its tangent line (one
global frame per point) and match two outlines by an order-preserving dynamic programme over
points. The two costs err on different pairs, so their weighted geometric mean
``ψ^(1 - w) h^w`` (:attr:`MatchConfig.height_weight`) ranks shapes better than either
(``benchmarks/eval_height_variants.py``; README, "A second distance fused in").

This module implements the distance from the paper's description, not from its code:

1. the outline is resampled to ``N`` points evenly in arc length, counter-clockwise;
2. row ``i`` of the descriptor holds the signed distances of the points ``i + 1, ..., i +
   N - 1`` (cyclically) to the line through point ``i`` parallel to ``p[i+1] - p[i-1]``,
   averaged in groups of ``g`` consecutive points (``g = round(3 N / 64)``: 3 at 64
   points, 5 at 100), and each column divided by its largest absolute value over the
   rows (scale invariance; entries in [-1, 1]). The groups are laid out symmetrically:
   when ``g`` divides ``N - 1`` they tile the other points; otherwise as many whole groups
   as fit in pairs are taken from the two ends (the points just after ``i`` and just
   before it) and the leftover points farthest along the curve are left out (at 100 points:
   9 groups from each end, points ``i + 46, ..., i + 54`` left out). So the descriptor of
   the mirror image is the descriptor with its columns reversed, which is what makes
   ``h`` symmetric;
3. matching point ``i`` of A to point ``j`` of B costs the weighted L1 distance of their
   rows, with weights ``1, 1/2, 1/3, ...`` on the entries nearest the point from either
   side (``"harmonic"``; or a Gaussian of ``N / 6`` points, ``"gauss"``), summing to 1;
4. ``h(A, B)`` is the cheapest order-preserving matching of A's points to B's, B taken
   cyclically from every start point, each point matched once or skipped at ``0.3`` times
   the mean point cost, against B as traced and mirrored (the cheaper kept), divided by
   ``N``;
5. optionally (``HeightParams.complexity``, :attr:`MatchConfig.height_complexity`), the
   paper's shape-complexity normalisation: ``h(A, B) / (C(A) + C(B))``, where the
   complexity ``C`` of an outline (:func:`complexity`) is the standard deviation of each
   descriptor column over the points, averaged over the columns (and over the outline as
   traced and mirrored). A circle has ``C = 0`` (every point sees the same heights); the
   more an outline's points see different shapes, the larger ``C``. The paper's reason:
   people notice a deformation of a simple contour more than one of a complex contour, so
   a difference between two simple outlines counts for more. The paper gives the idea and
   builds ``C`` from standard deviations of the descriptor; this exact form is ours.

``h`` is invariant to translation, rotation, scale, start point and mirroring, and symmetric:
``h(A, B) = h(B, A)`` (the cyclic programme over every start covers every alignment either
way round); so is its normalised form.

The pure-Python oracle is :func:`shapetree.matching._reference.reference_height_distance`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from shapetree.curves import resample

__all__ = [
    "HeightParams",
    "HeightRows",
    "complexity",
    "dp_cyclic",
    "group_starts",
    "height_descriptors",
    "height_distance",
    "height_matrix",
    "heights",
]


@dataclass(frozen=True)
class HeightParams:
    """The parameters of one height-function distance.

    Attributes
    ----------
    n_points : int
        Points evenly in arc length (:attr:`MatchConfig.height_points`).
    group : int
        Consecutive heights averaged into one descriptor entry.
    weighting : {"harmonic", "gauss"}
        Weights of the entries by their distance along the curve from the point.
    skip : float
        Cost of leaving a point unmatched, in units of the pair's mean point cost.
    complexity : bool
        Divide ``h(A, B)`` by ``C(A) + C(B)`` (:func:`complexity`; step 5 above).
    """

    n_points: int = 100
    group: int = 5
    weighting: str = "harmonic"
    skip: float = 0.3
    complexity: bool = False

    @classmethod
    def of(cls, n_points: int, complexity: bool = False) -> HeightParams:
        """The parameters :class:`MatchConfig` uses at ``n_points`` points (harmonic
        weights, groups of ``round(3 n / 64)``), with or without the complexity
        normalisation."""
        return cls(int(n_points), max(1, round(3 * n_points / 64)), complexity=bool(complexity))

    @property
    def n_entries(self) -> int:
        return len(group_starts(self.n_points, self.group))

    def weights(self) -> np.ndarray:
        """``(n_entries,)`` weights of the descriptor entries, summing to 1."""
        m = self.n_entries
        if self.weighting == "harmonic":
            k = np.arange(m)
            w = 1.0 / np.minimum(k + 1, m - k)
        elif self.weighting == "gauss":
            centre = group_starts(self.n_points, self.group) + (self.group - 1) / 2.0
            d = np.minimum(centre, self.n_points - centre)
            w = np.exp(-0.5 * (d / (self.n_points / 6.0)) ** 2)
        else:
            raise ValueError(f"weighting must be 'harmonic' or 'gauss', not {self.weighting!r}")
        return w / w.sum()


def group_starts(n: int, group: int) -> np.ndarray:
    """The first point (``k`` steps along the curve, ``1 <= k <= n - 1``) of each group of
    ``group`` consecutive heights in the descriptor of an ``n``-point curve, symmetric under
    ``k -> n - k`` (step 2 of the module's description).

    >>> group_starts(10, 3).tolist()  # 9 points: 3 groups tile them
    [1, 4, 7]
    >>> group_starts(100, 5).tolist()[8:10]  # 99 points: 9 groups from each end
    [41, 55]
    """
    m = (n - 1) // group
    if (n - 1) % group == 0:
        return 1 + group * np.arange(m)
    half = m // 2
    if half == 0:
        raise ValueError(f"{n} points leave no two groups of {group} heights")
    near = 1 + group * np.arange(half)
    return np.concatenate([near, n - group - near[::-1] + 1])


def heights(p: np.ndarray, group: int) -> np.ndarray:
    """The smoothed, normalised height descriptor of ordered points of a closed curve.

    Parameters
    ----------
    p : (n, 2) float array
        Points of a closed curve, in order, counter-clockwise.
    group : int
        Consecutive heights averaged into one entry.

    Returns
    -------
    (n, len(group_starts(n, group))) float array
        Row ``i``: the signed distances of the points ``i + 1, i + 2, ...`` (cyclically) to
        the tangent line at point ``i`` (direction ``p[i+1] - p[i-1]``), averaged in the
        groups of :func:`group_starts`, each column divided by its largest absolute value
        over the rows (values in [-1, 1]; a column of zeros stays zero).
    """
    n = len(p)
    t = np.roll(p, -1, 0) - np.roll(p, 1, 0)
    t = t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300)
    normal = np.stack([-t[:, 1], t[:, 0]], 1)
    idx = (np.arange(n)[:, None] + np.arange(1, n)[None, :]) % n
    h = ((p[idx] - p[:, None, :]) * normal[:, None, :]).sum(-1)
    cols = group_starts(n, group)[:, None] - 1 + np.arange(group)  # (entries, group)
    f = h[:, cols].mean(-1)
    scale = np.abs(f).max(0, keepdims=True)
    return f / np.where(scale > 0, scale, 1.0)


def height_descriptors(curve: np.ndarray, hp: HeightParams) -> tuple[np.ndarray, np.ndarray]:
    """The descriptor of a closed outline as traced and mirrored (left to right).

    Parameters
    ----------
    curve : (k, 2) float array
        A validated closed outline (any orientation, any start, any sampling).
    hp : HeightParams

    Returns
    -------
    plain, mirrored : (hp.n_points, hp.n_entries) float arrays
        :func:`heights` of the outline resampled to ``hp.n_points`` points and oriented
        counter-clockwise, and of its mirror image (likewise oriented).
    """
    p = resample(np.asarray(curve, dtype=np.float64), hp.n_points, closed=True)
    out = []
    for q in (p, p * np.array([-1.0, 1.0])):
        x, y = q[:, 0], q[:, 1]
        if (x * np.roll(y, -1) - np.roll(x, -1) * y).sum() < 0:
            q = q[::-1]
        out.append(np.ascontiguousarray(heights(np.ascontiguousarray(q), hp.group)))
    return out[0], out[1]


@njit(cache=True, nogil=True)
def dp_cyclic(C: np.ndarray, pen: float) -> float:
    """The cheapest order-preserving matching of the rows of ``C`` to its columns, the
    columns taken cyclically from every start: each row and column is matched once or
    skipped at cost ``pen``; a matched pair ``(i, j)`` costs ``C[i, j]``.

    O(n m^2) time, O(m^2) memory: the tables of all ``m`` starts are filled together, row by
    row, the start the innermost (contiguous) index, so the compiler vectorises it; each
    start's table holds the numbers a table of its own would (the same additions in the same
    order), so the result is exact."""
    n, m = C.shape
    C2 = np.empty((n, 2 * m))  # the columns twice: start s reads C2[:, s : s + m]
    C2[:, :m] = C
    C2[:, m:] = C
    prev = np.empty((m + 1, m))  # prev[j, s]: row i - 1 of start s's table
    cur = np.empty((m + 1, m))
    for j in range(m + 1):
        for s in range(m):
            prev[j, s] = j * pen
    for i in range(1, n + 1):
        for s in range(m):
            cur[0, s] = i * pen
        row = C2[i - 1]
        for j in range(1, m + 1):
            diag, up, left, out = prev[j - 1], prev[j], cur[j - 1], cur[j]
            for s in range(m):
                v = diag[s] + row[j - 1 + s]
                a = up[s] + pen
                if a < v:
                    v = a
                b = left[s] + pen
                if b < v:
                    v = b
                out[s] = v
        prev, cur = cur, prev
    best = np.inf
    for s in range(m):
        if prev[m, s] < best:
            best = prev[m, s]
    return best


@njit(cache=True, nogil=True)
def _point_costs(fa: np.ndarray, fb: np.ndarray, w: np.ndarray) -> np.ndarray:
    n, k = fa.shape
    C = np.empty((n, fb.shape[0]))
    for p in range(n):
        for q in range(fb.shape[0]):
            s = 0.0
            for e in range(k):
                s += w[e] * abs(fa[p, e] - fb[q, e])
            C[p, q] = s
    return C


@njit(cache=True, nogil=True)
def _pair(fa: np.ndarray, fb: np.ndarray, fb_mirror: np.ndarray, w: np.ndarray, skip: float):
    best = np.inf
    for k in range(2):
        C = _point_costs(fa, fb if k == 0 else fb_mirror, w)
        v = dp_cyclic(C, skip * C.mean())
        if v < best:
            best = v
    return best / fa.shape[0]


@njit(cache=True, nogil=True)
def _column(FA: np.ndarray, fb: np.ndarray, fb_mirror: np.ndarray, w: np.ndarray, skip: float):
    # serial: the retrieval engine runs its row blocks in threads (numba's parallel
    # threading layer must not be entered from several threads at once)
    out = np.empty(FA.shape[0])
    for i in range(FA.shape[0]):
        out[i] = _pair(FA[i], fb, fb_mirror, w, skip)
    return out


#: Smallest denominator ``C(A) + C(B)`` of the normalised distance, so that two circles
#: (``C`` and ``h`` both 0 up to rounding) are at distance ~0, not rounding / rounding. Real
#: outlines have ``C`` of 0.3-0.5; at 0.01 an outline is all but a circle.
MIN_COMPLEXITY = 0.01


def complexity(desc: tuple[np.ndarray, np.ndarray]) -> float:
    """The shape complexity ``C`` of an outline given by its :func:`height_descriptors`.

    The population standard deviation of each descriptor column over the outline's points,
    averaged over the columns, for the outline as traced and mirrored, and the two averaged
    (the two are equal up to rounding, the mirror's columns being the same columns
    reversed; averaging makes ``C`` mirror invariant exactly). 0 for a circle; about
    0.3-0.5 for the silhouettes of MPEG-7, Kimia-99 and the Swedish leaves.
    """
    return float(0.5 * (desc[0].std(axis=0).mean() + desc[1].std(axis=0).mean()))


def height_distance(
    a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray], hp: HeightParams
) -> float:
    """``h(A, B)`` of two outlines given by their :func:`height_descriptors` (divided by
    ``C(A) + C(B)`` when ``hp.complexity``)."""
    h = float(_pair(a[0], b[0], b[1], hp.weights(), float(hp.skip)))
    if hp.complexity:
        h /= max(complexity(a) + complexity(b), MIN_COMPLEXITY)
    return h


class HeightRows:
    """Several outlines' descriptors, stacked once, to be matched against one outline after
    another (the retrieval engine's row blocks).

    Parameters
    ----------
    rows : list of (plain, mirrored) descriptor pairs
        :func:`height_descriptors` of each row outline.
    hp : HeightParams
    """

    def __init__(self, rows: list[tuple[np.ndarray, np.ndarray]], hp: HeightParams) -> None:
        self.FA = np.stack([d[0] for d in rows]) if rows else np.empty((0, hp.n_points, 0))
        self.w = hp.weights()
        self.skip = float(hp.skip)
        self.C = np.array([complexity(d) for d in rows]) if hp.complexity else None

    def against(self, col: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
        """``(len(rows),)`` distances ``h(row_i, col)`` (compiled; releases the GIL)."""
        if self.FA.shape[0] == 0:
            return np.empty(0)
        h = _column(self.FA, col[0], col[1], self.w, self.skip)
        if self.C is not None:
            h /= np.maximum(self.C + complexity(col), MIN_COMPLEXITY)
        return h


def height_matrix(
    rows: list[tuple[np.ndarray, np.ndarray]],
    cols: list[tuple[np.ndarray, np.ndarray]],
    hp: HeightParams,
) -> np.ndarray:
    """``(len(rows), len(cols))`` height-function distances of outlines given by their
    :func:`height_descriptors`."""
    stack = HeightRows(rows, hp)
    out = np.empty((len(rows), len(cols)))
    for j, col in enumerate(cols):
        out[:, j] = stack.against(col)
    return out
