"""The compiled kernels: fast-math flags, the finite sentinel, and zero-size target triangles."""

from __future__ import annotations

import inspect
import re
import zlib

import numba
import numpy as np
import pytest
from _shapes import blob
from numba.core.cpu import FastMathOptions

from shapetree.detection import _stitch
from shapetree.geometry import DEGENERATE_DIF, triangle_dif
from shapetree.geometry import _dif as dif_module
from shapetree.geometry._dif import FASTMATH
from shapetree.matching import (
    MatchParams,
    match_cost,
    match_prepared,
    prepare_model,
    prepare_target,
    subcurve_table,
)
from shapetree.matching import _kernels as kernels
from shapetree.matching._batch import ModelStack
from shapetree.matching._match import _bands, _buffers
from shapetree.matching._reference import _dif as oracle_dif
from shapetree.matching._reference import (
    reference_correspondence,
    reference_match_cost,
    reference_score,
    reference_subcurve_table,
)
from shapetree.tree import build_shape_tree

UNSAFE = {"fast", "nnan", "ninf"}
P, A, B = (0.0, 0.0), (1.0, 1.0), (1.0, -1.0)
KERNELS = [
    kernels.fill_tables,
    kernels.node_row,
    kernels.one_split,
    kernels.replace_row,
    kernels.length_chunk,
    kernels.closed_root_min,
    kernels.closed_costs,
    kernels.target_tables,
]
SHARED = [
    getattr(dif_module, name)
    for name in dif_module.__all__
    if isinstance(getattr(dif_module, name), numba.core.registry.CPUDispatcher)
]


def _seed(*key: object) -> int:
    return zlib.crc32(repr(key).encode())


def _clover() -> np.ndarray:
    """A closed three-leaf clover through P three times (9 points): (P, P, P) triangles,
    some of them wrapping around the start."""
    leaf = np.array([(1.0, 0.5), (1.4, -0.2)])
    c, s = np.cos(2 * np.pi / 3), np.sin(2 * np.pi / 3)
    rot = np.array([[c, -s], [s, c]])
    return np.vstack([np.vstack([P, leaf @ np.linalg.matrix_power(rot, r).T]) for r in range(3)])


def _flags(dispatcher) -> set[str]:
    return set(FastMathOptions(dispatcher.targetoptions.get("fastmath", False)).flags)


# --- fast-math flags and the sentinel -------------------------------------------------


def test_fastmath_constant_has_no_nan_or_inf_assumptions():
    assert not UNSAFE & FASTMATH
    assert {"contract", "reassoc"} <= FASTMATH


@pytest.mark.parametrize("fn", KERNELS + SHARED, ids=lambda f: f.__name__)
def test_kernels_compile_with_the_explicit_flag_set(fn):
    assert _flags(fn) == set(FASTMATH)


def test_stitching_kernels_assume_nothing_about_nan_and_inf():
    for fn in (_stitch._stitch_kernel, _stitch._dif, _stitch._difn, _stitch._shape):
        assert not UNSAFE & _flags(fn)


def test_compiled_fill_tables_ir_has_no_nnan_or_ninf():
    """Compile fill_tables afresh (cached code cannot be inspected) and read its LLVM IR:
    no instruction may carry the flags that assume no NaN / inf, inlined callees included;
    both specialisations (a target with and without zero-size triangles)."""
    t = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    a = np.c_[np.cos(t), np.sin(t)]
    plain, clover = prepare_target(a), prepare_target(_clover())
    assert plain.deg is None and clover.deg is not None
    for target in (plain, clover):
        match_cost(prepare_model(a[:6]), target)  # makes sure both signatures exist
    sigs = [s for s in kernels.fill_tables.signatures if str(s[2].dtype) == "float64"]
    assert {str(s[11]) for s in sigs} >= {"none", "array(uint8, 2d, C)"}
    opts = {k: v for k, v in kernels.fill_tables.targetoptions.items() if k == "fastmath"}
    for sig in sigs:
        fresh = numba.njit(sig, cache=False, nogil=True, **opts)(kernels.fill_tables.py_func)
        ir = fresh.inspect_llvm(sig)
        assert not set(re.findall(r"\b(fast|nnan|ninf)\b", ir))
        assert re.search(r"\b(reassoc|contract)\b", ir)  # the flags we do ask for are there


def test_kernels_store_no_infinity():
    for fn in KERNELS:
        assert "np.inf" not in inspect.getsource(fn.py_func)
    assert kernels.SENTINEL < np.finfo(np.float32).max / 4
    assert np.isinf(kernels.finite_or_inf(np.float32(kernels.SENTINEL)))
    assert kernels.finite_or_inf(2.5) == 2.5
    out = kernels.finite_or_inf(np.array([1.0, 0.6e30, 2e30], np.float32))
    assert out.dtype == np.float32 and out[0] == 1 and np.isinf(out[1:]).all()


def _no_split_bands(td, m, band):
    """Bands under which the root of an open tree has no admissible split at L = m - 1:
    both children may only use one target segment."""
    lmin, lmax = (x.copy() for x in _bands(td, m, None))
    root = td.tree.roots[0]
    for child in (td.left_tab[root], td.right_tab[root]):
        lmin[child] = lmax[child] = 1
    td.band_cache[(m, band)] = (lmin, lmax)


def test_no_admissible_split_costs_inf_not_garbage():
    rng = np.random.default_rng(_seed("no-split"))
    a, b = blob(9, rng, closed=False), blob(11, rng, closed=False)
    model, target = prepare_model(a, closed=False), prepare_target(b, closed=False)
    band = 1.25
    _no_split_bands(model.trees[0], target.n_points, band)
    ws = _buffers(model.trees[0].n_tables, target.n_points)
    ws[:] = np.nan  # whatever the reused workspace held must not leak into the result
    params = MatchParams(band=band)
    assert match_cost(model, target, params) == np.inf
    res = match_prepared(model, target, params)
    assert res.cost == np.inf and np.isinf(res.costs).all()
    assert np.isnan(res.a_to_b).all() and res.replaced == []
    # a replacement covers it: the root is replaced at κ λ (|A| + |B|) = 2 κ
    occ = MatchParams(band=band, occlusion=0.4)
    assert match_cost(model, target, occ) == pytest.approx(0.8, rel=1e-12)
    res = match_prepared(model, target, occ)
    assert res.cost == pytest.approx(0.8, rel=1e-12)
    assert res.replaced == [(0, 8, 0, 10)]


def test_no_admissible_closed_alignment_costs_inf_everywhere():
    rng = np.random.default_rng(_seed("no-alignment"))
    models = [prepare_model(blob(10, rng), n_trees=2) for _ in range(3)]
    target = prepare_target(blob(12, rng))
    band = 1.75
    m = target.n_points
    for mod in models[1:]:  # model 0 keeps its normal band
        for td in mod.trees:
            lmin, lmax = (x.copy() for x in _bands(td, m, band))
            for half in (0, 1):
                r = td.table_of_root(td.tree.roots[half], half)
                lmin[r] = lmax[r] = 1  # 1 + 1 target segments cannot close a loop of 12
            td.band_cache[(m, band)] = (lmin, lmax)
    params = MatchParams(band=band)
    costs = [match_cost(mod, target, params) for mod in models]
    assert np.isfinite(costs[0]) and costs[1:] == [np.inf, np.inf]
    np.testing.assert_array_equal(ModelStack(models, m, params).costs(target), costs)
    res = match_prepared(models[1], target, params)
    assert res.cost == np.inf and np.isnan(res.a_to_b).all()


def test_subcurve_table_has_inf_only_in_column_zero():
    rng = np.random.default_rng(_seed("subcurve-inf"))
    table = subcurve_table(blob(6, rng, closed=False), prepare_target(blob(9, rng)))
    assert np.isinf(table[:, 0]).all() and np.isfinite(table[:, 1:]).all()


# --- zero-size target triangles -------------------------------------------------------


def _kernel_cost(a, b, closed, **params):
    return match_prepared(
        prepare_model(a, closed=closed), prepare_target(b, closed=closed), MatchParams(**params)
    ).cost


def test_coincident_target_points_cost_as_in_the_oracle():
    """The repro: a straight 3-point model vs the target P, A, P, B, P. Splitting at the
    middle P gives the target triangle (P, P, P), which has no shape (dif = 1)."""
    a = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    b = np.array([P, A, P, B, P])
    ref = reference_match_cost(build_shape_tree(a, closed=False), b)
    assert ref == pytest.approx(1.3511904761904763, rel=1e-12)
    assert _kernel_cost(a, b, False) == pytest.approx(ref, rel=1e-12)
    t = prepare_target(b, closed=False)
    assert t.deg is not None and t.deg[4, 2] == 1 and t.deg.sum() == 1  # (b0, b2, b4)
    np.testing.assert_array_equal(t.tri[4, 2, :, 0], 0.0)


def test_degenerate_rule_is_the_same_everywhere():
    pt = np.array([P, P, P])
    other = np.array([P, A, B])
    needle = np.array([P, A, P])  # first == last: a shape, not degenerate
    z = [complex(*p) for p in other]
    for x in (pt, other, needle):
        for y in (pt, other, needle):
            expected = oracle_dif(x, y)
            assert float(triangle_dif(x, y)) == pytest.approx(expected, abs=1e-12)
            zx, zy = ([complex(*p) for p in t] for t in (x, y))
            assert _stitch._dif(*zx, *zy) == pytest.approx(expected, abs=1e-12)
    assert oracle_dif(pt, pt) == DEGENERATE_DIF == 1.0
    assert oracle_dif(pt, other) == 1.0 and _stitch._dif(*z, 0j, 0j, 0j) == 1.0
    assert oracle_dif(needle, needle) == pytest.approx(0.0, abs=1e-15)


def _with_repeats(n: int, rng: np.random.Generator, closed: bool) -> np.ndarray:
    """A blob (``n >= 6``) in which three points, no two of them neighbours, are the same
    point: a zero-size target triangle (and needles, triangles whose ends coincide)."""
    b = blob(n, rng, closed=closed)
    while True:
        idx = np.sort(rng.choice(n, size=3, replace=False))
        gaps = np.diff(np.r_[idx, idx[0] + n]) if closed else np.diff(idx)
        if gaps.min() >= 2:
            b[idx] = b[idx[0]]
            return b


# --- the order of the table fill -----------------------------------------------------


def _tables(model, target, params, chunk):
    td = model.trees[0]
    m = target.n_points
    lmin, lmax = _bands(td, m, params.band)
    dt = target.tri.dtype
    tab = np.full((td.n_tables, m, 2 * m), -7.0, dtype=dt)  # unwritten entries stay -7
    kernels.fill_tables(
        td.left_tab,
        td.right_tab,
        *td.kernel_arrays(dt),
        target.tri,
        target.deg,
        target.base_table(params.dif),
        target.blen,
        target.closed,
        params.kernel_occlusion,
        float(params.segment_weight),
        lmin,
        lmax,
        tab,
        params.hyper,
        chunk,
    )
    return tab


@pytest.mark.parametrize("closed", [False, True])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_table_fill_order_changes_no_bit(closed, dtype):
    """fill_tables fills the nodes' rows by chunks of target lengths; one chunk holding
    every length is the node-by-node order. Every chunk size gives the same tables, bit
    for bit, with bands, occlusion, the hyperbolic dif and zero-size target triangles."""
    rng = np.random.default_rng(_seed("fill-order", closed, np.dtype(dtype).name))
    cases = [(blob(int(rng.integers(6, 15)), rng, closed=closed), None) for _ in range(3)]
    if closed:
        cases.append((blob(8, rng), _clover()))
    for a, b in cases:
        if b is None:
            b = blob(int(rng.integers(12, 30)), rng, closed=closed)
        target = prepare_target(b, closed=closed, dtype=dtype)
        m = target.n_points
        for dif in ("procrustes", "hyperbolic"):
            model = prepare_model(a, closed=closed, dif=dif)
            for band, occlusion in ((None, None), (3.0, None), (2.0, 0.5), (None, 0.5)):
                params = MatchParams(band=band, occlusion=occlusion, dif=dif)
                one = _tables(model, target, params, 10**6)
                for chunk in (1, 2, 5, 0):
                    np.testing.assert_array_equal(_tables(model, target, params, chunk), one)
                assert (one[:, 1:, :m] != -7).any()  # rows were written


def test_length_chunk_keeps_a_chunk_of_triangle_planes_near_the_budget():
    assert kernels.length_chunk(200, 4) == 1  # one plane is 480 kB: no room for two
    assert kernels.length_chunk(10_000, 8) == 1  # never 0
    for m, size in ((50, 8), (64, 4), (100, 4)):
        c = kernels.length_chunk(m, size)
        assert c >= 2
        assert c * 3 * m * m * size <= kernels.CHUNK_BYTES < (c + 1) * 3 * m * m * size


@pytest.mark.parametrize("closed", [False, True])
@pytest.mark.parametrize("occlusion", [None, 0.5])
def test_kernel_equals_reference_on_targets_with_repeated_points(closed, occlusion):
    rng = np.random.default_rng(_seed("repeats", closed, occlusion))
    for _ in range(10):
        n, m = int(rng.integers(4, 11)), int(rng.integers(7, 12))
        a, b = blob(n, rng, closed=closed), _with_repeats(m, rng, closed)
        t = prepare_target(b, closed=closed)
        assert t.n_points == m
        assert t.deg is not None and t.deg.any()
        tree = build_shape_tree(a, closed=closed)
        ref = reference_match_cost(tree, b, occlusion=occlusion)
        assert _kernel_cost(a, b, closed, occlusion=occlusion) == pytest.approx(
            ref, rel=1e-9, abs=1e-12
        )


def test_degenerate_targets_in_every_entry_point():
    """Tables, float32 stacks, subcurve tables and the traceback all apply the rule."""
    b = _clover()
    rng = np.random.default_rng(_seed("entry-points"))
    a = blob(7, rng)
    tree = build_shape_tree(a, closed=True)
    t64, t32 = prepare_target(b), prepare_target(b, dtype=np.float32)
    assert t64.deg is not None and t64.deg.any() and t32.deg is not None
    ref = reference_match_cost(tree, b)
    model = prepare_model(a)
    assert match_cost(model, t64) == pytest.approx(ref, rel=1e-9)
    assert match_cost(model, t32) == pytest.approx(ref, rel=1e-5)
    assert ModelStack([model], 9).costs(t64)[0] == pytest.approx(ref, rel=1e-9)
    assert ModelStack([model], 9, dtype=np.float32).costs(t32)[0] == pytest.approx(ref, rel=1e-5)
    res = match_prepared(model, t64)
    assert reference_score(tree, b, res.a_to_b, res.replaced) == pytest.approx(ref, rel=1e-9)
    cost, mapping, unique = reference_correspondence(tree, b)
    if unique:
        for ia, jb in mapping.items():
            assert res.a_to_b[ia % 7] == pytest.approx(jb % 9)
    contour = blob(5, rng, closed=False)
    ctree = build_shape_tree(contour, closed=False)
    np.testing.assert_allclose(
        subcurve_table(ctree, t64)[:, 1:],
        reference_subcurve_table(ctree, b)[:, 1:],
        rtol=1e-9,
        atol=1e-12,
    )
