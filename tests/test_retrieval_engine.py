"""Distance-matrix engine: exactness, block cache, corruption, resumption after SIGKILL."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from shapetree import ShapeTreeError
from shapetree.curves import resample
from shapetree.matching import (
    PRESETS,
    MatchParams,
    match_cost,
    mirror_curve,
    prepare_model,
    prepare_target,
)
from shapetree.retrieval import directed_costs as _directed_costs
from shapetree.retrieval import distance_matrix as _distance_matrix
from shapetree.retrieval._engine import read_block, write_block

#: the literal matcher on the given sampling: the options these tests change start from it
RAW = PRESETS["paper"]


def directed_costs(*args, **kw):
    return _directed_costs(*args, **{"config": RAW, **kw})


def distance_matrix(*args, **kw):
    if kw.get("symmetrize", "") is None:
        kw["symmetrize"] = "none"
    kw.setdefault("symmetrize", "min")
    return _distance_matrix(*args, **{"config": RAW, **kw})


def _shapes(k: int = 6, n: int = 60, seed: int = 0) -> list[np.ndarray]:
    """Smooth random star-shaped closed curves, counter-clockwise."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    out = []
    for _ in range(k):
        r = 1 + sum(rng.uniform(-0.25, 0.25) * np.cos(f * t + rng.uniform(0, 6)) for f in (2, 3, 5))
        out.append(np.c_[r * np.cos(t) * rng.uniform(0.6, 1.4), r * np.sin(t)])
    return out


def test_mirror_curve_keeps_orientation() -> None:
    from shapetree.curves import signed_area

    c = _shapes(1)[0]
    m = mirror_curve(c)
    assert signed_area(c) > 0 and signed_area(m) == pytest.approx(signed_area(c))
    assert np.allclose(mirror_curve(m), c)


def test_matrix_equals_direct_match_cost() -> None:
    curves = _shapes(5)
    n, occ, nt = 20, 1.0, 2
    rs = [resample(c, n, closed=True) for c in curves]
    c = directed_costs(
        curves,
        n_points=n,
        occlusion=occ,
        n_trees=nt,
        mirror=True,
        workers=2,
        block=2,
        progress=False,
        precision="float64",
    )
    assert c.shape == (2, 5, 5)
    # the default float32 tables agree to about 1e-6 relative
    c32 = directed_costs(
        curves, n_points=n, occlusion=occ, n_trees=nt, mirror=True, workers=1, progress=False
    )
    np.testing.assert_allclose(c32, c, rtol=2e-5, atol=1e-9)
    assert not np.array_equal(c32, c)
    mp = MatchParams(occlusion=occ)
    for i, a in enumerate(rs):
        for j, b in enumerate(rs):
            t = prepare_target(b)
            # the engine's batched kernel call rounds like match_cost to within 1e-12
            want = match_cost(prepare_model(a, n_trees=nt), t, mp)
            assert c[0, i, j] == pytest.approx(want, rel=1e-12, abs=1e-15)
            want = match_cost(prepare_model(mirror_curve(a), n_trees=nt), t, mp)
            assert c[1, i, j] == pytest.approx(want, rel=1e-12, abs=1e-15)
    d = distance_matrix(
        curves,
        n_points=n,
        occlusion=occ,
        n_trees=nt,
        mirror=True,
        symmetrize="min",
        workers=1,
        progress=False,
        precision="float64",
    )
    assert np.array_equal(d, np.minimum(c.min(0), c.min(0).T))
    d_none = distance_matrix(
        curves,
        n_points=n,
        occlusion=occ,
        n_trees=nt,
        symmetrize=None,
        workers=1,
        progress=False,
        precision="float64",
    )
    assert np.array_equal(d_none, c[0])
    assert np.allclose(np.diag(d_none), 0.0)


def test_rectangular_variant() -> None:
    curves = _shapes(5)
    q, db = curves[:2], curves[2:]
    full = directed_costs(curves, n_points=16, workers=1, progress=False)[0]
    fwd = distance_matrix(q, db, n_points=16, symmetrize=None, progress=False)
    assert np.array_equal(fwd, full[:2, 2:])
    mean = distance_matrix(q, db, n_points=16, symmetrize="mean", progress=False)
    assert np.allclose(mean, 0.5 * (full[:2, 2:] + full[2:, :2].T))
    rev = distance_matrix(q, db, n_points=16, symmetrize="reverse", progress=False)
    assert np.array_equal(rev, full[2:, :2].T)


def test_bad_parameters() -> None:
    curves = _shapes(2)
    with pytest.raises(ShapeTreeError):
        distance_matrix(curves, symmetrize="median", progress=False)
    with pytest.raises(ShapeTreeError):
        distance_matrix(curves, occlusion=-1.0, progress=False)
    with pytest.raises(ShapeTreeError):
        distance_matrix(curves, n_trees=0, progress=False)


def test_cache_reuse_key_and_corruption(tmp_path: Path) -> None:
    curves = _shapes(6)
    kw = dict(n_points=16, block=2, progress=False, workers=2)
    ref = directed_costs(curves, **kw)
    c1 = directed_costs(curves, cache_dir=tmp_path, **kw)
    assert np.array_equal(c1, ref)
    (folder,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    blocks = sorted(folder.glob("*.blk"))
    assert len(blocks) == 3 and (folder / "params.json").is_file()
    # second run reads the blocks (poison one value *with* a valid checksum to prove it)
    raw = blocks[0].read_bytes()
    hdr = json.loads(raw[raw.index(b"{") : raw.index(b"}") + 1])
    arr = read_block(blocks[0], {"key": hdr["key"]})
    arr[0, 0, 1] = 123.0
    write_block(blocks[0], arr, {"key": hdr["key"], "rows": hdr["rows"]})
    assert directed_costs(curves, cache_dir=tmp_path, **kw)[0, 0, 1] == 123.0
    # flip a payload byte: detected (checksum), recomputed, rewritten
    raw = bytearray(blocks[1].read_bytes())
    raw[-3] ^= 0xFF
    blocks[1].write_bytes(bytes(raw))
    # truncate another one
    blocks[2].write_bytes(blocks[2].read_bytes()[:40])
    with pytest.warns(UserWarning, match="damaged"):
        c2 = directed_costs(curves, cache_dir=tmp_path, **kw)
    assert np.array_equal(c2[:, 2:], ref[:, 2:])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # blocks were rewritten: no more warnings
        directed_costs(curves, cache_dir=tmp_path, **kw)
    # a different parameter is a different key (new folder)
    directed_costs(curves, cache_dir=tmp_path, **dict(kw, occlusion=2.0))
    assert len([p for p in tmp_path.iterdir() if p.is_dir()]) == 2


_CHILD = textwrap.dedent(
    """
    import sys
    import numpy as np
    sys.path.insert(0, {tests!r})
    from test_retrieval_engine import _shapes, distance_matrix
    d = distance_matrix(_shapes(40, seed=5), n_points=36, mirror=True, block=1, workers=2,
                        cache_dir={cache!r}, progress=False)
    np.save({out!r}, d)
    """
)


def test_sigkill_midway_then_resume(tmp_path: Path) -> None:
    cache, out = tmp_path / "cache", tmp_path / "d.npy"
    code = _CHILD.format(tests=str(Path(__file__).parent), cache=str(cache), out=str(out))
    proc = subprocess.Popen([sys.executable, "-c", code])
    try:
        deadline = time.time() + 120
        n_blocks = 0
        while time.time() < deadline and proc.poll() is None:
            n_blocks = len(list(cache.glob("*/*.blk")))
            if n_blocks >= 3:
                break
            time.sleep(0.01)
        assert proc.poll() is None, "child finished before it could be killed"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == -signal.SIGKILL
    n_after = len(list(cache.glob("*/*.blk")))
    assert 3 <= n_after < 40
    assert not out.exists()
    kw = dict(n_points=36, mirror=True, block=1, progress=False)
    resumed = distance_matrix(_shapes(40, seed=5), cache_dir=cache, workers=2, **kw)
    fresh = distance_matrix(_shapes(40, seed=5), workers=1, **kw)
    assert np.array_equal(resumed, fresh)
    assert len(list(cache.glob("*/*.blk"))) == 40


def test_length_power_reaches_the_matcher():
    from shapetree.matching import match_cost, prepare_model, prepare_target

    curves = _shapes(5, seed=3)
    D = distance_matrix(
        curves,
        n_points=20,
        length_power=1.5,
        symmetrize=None,
        workers=1,
        progress=False,
        precision="float64",
    )
    from shapetree.curves import resample

    pts = [resample(c, 20, closed=True) for c in curves]
    ref = match_cost(
        prepare_model(pts[1], length_power=1.5), prepare_target(pts[3], length_power=1.5)
    )
    assert D[1, 3] == pytest.approx(ref, rel=1e-12)
    plain = distance_matrix(curves, n_points=20, symmetrize=None, workers=1, progress=False)
    assert not np.allclose(D, plain)


def test_smooth_reaches_the_matcher_and_the_cache_key(tmp_path: Path):
    from shapetree.curves import smooth

    curves = _shapes(4, n=200, seed=5)
    kw = dict(n_points=24, symmetrize=None, workers=1, progress=False, cache_dir=tmp_path)
    kw["precision"] = "float64"  # compared with match_cost (float64) to 1e-12
    D = distance_matrix(curves, smooth=0.01, **kw)
    pts = [resample(smooth(c, 0.01, closed=True), 24, closed=True) for c in curves]
    ref = match_cost(prepare_model(pts[2]), prepare_target(pts[0]))
    assert D[2, 0] == pytest.approx(ref, rel=1e-12)
    plain = distance_matrix(curves, **kw)
    assert not np.allclose(D, plain)
    assert len([p for p in tmp_path.iterdir() if p.is_dir()]) == 2  # two cache keys
    with pytest.raises(ShapeTreeError, match="smooth"):
        distance_matrix(curves, smooth=0.7, **kw)


def test_phases_and_dense_targets_reach_the_matcher():
    """phases = min over target resamplings at p/P of a spacing; target_factor and
    segment_weight change the target's size and the base case: each entry equals the
    matching computed directly."""
    curves = _shapes(4, seed=7)
    n = 16
    kw = dict(n_points=n, symmetrize=None, workers=1, progress=False, precision="float64")
    D = distance_matrix(curves, phases=3, **kw)
    E = distance_matrix(curves, target_factor=2, segment_weight=0.0, **kw)
    for i, j in [(0, 1), (2, 3), (3, 0)]:
        model = prepare_model(resample(curves[i], n, closed=True))
        want = min(
            match_cost(model, prepare_target(resample(curves[j], n, closed=True, phase=p / 3)))
            for p in range(3)
        )
        assert D[i, j] == pytest.approx(want, rel=1e-12, abs=1e-15)
        dense = prepare_target(resample(curves[j], 2 * n, closed=True))
        want = match_cost(model, dense, MatchParams(segment_weight=0.0))
        assert E[i, j] == pytest.approx(want, rel=1e-12, abs=1e-15)
    plain = distance_matrix(curves, **kw)
    off = ~np.eye(4, dtype=bool)
    assert np.all(D[off] <= plain[off] + 1e-15)  # phase 0 is among the phases tried
    assert not np.allclose(E, plain)


@pytest.mark.parametrize(
    "bad, words",
    [
        (dict(phases=0), "phases must be an integer >= 1"),
        (dict(phases=2.5), "phases must be an integer >= 1"),
        (dict(target_factor=0), "target_factor must be an integer >= 1"),
        (dict(segment_weight=-1.0), "segment_weight must be a number >= 0"),
        (dict(phases=2, n_points=None), "need n_points"),
        (dict(target_factor=2, n_points=None), "need n_points"),
        (dict(precision="half"), "precision must be one of"),
    ],
)
def test_bad_sampling_options_are_named(bad, words):
    kw = dict(dict(n_points=12, workers=1, progress=False), **bad)
    with pytest.raises(ShapeTreeError, match=words):
        distance_matrix(_shapes(3, seed=1), **kw)


@pytest.mark.parametrize("block", [0, -2, 2.5, True, "4"])
def test_bad_block_is_named(block) -> None:
    with pytest.raises(ShapeTreeError, match="block must be an integer >= 1 or None"):
        distance_matrix(_shapes(3), n_points=12, block=block, workers=1, progress=False)


def test_threads_stats_name_the_engine() -> None:
    stats: dict = {}
    c = directed_costs(_shapes(3), n_points=12, block=1, workers=1, progress=False, stats=stats)
    assert stats["engine"] == "threads" and stats["pairs_computed"] == 9 and c.shape[1:] == (3, 3)
