"""The prepared shape database (``ShapeIndex``, ``.stidx``): round trip, use by the engine,
refusal of a mismatched database, corruption, atomic writes, and ``shapetree index``."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

import shapetree
from shapetree import ShapeTreeError
from shapetree.cli import main
from shapetree.demo import demo_shape
from shapetree.matching import MatchConfig
from shapetree.matching._api import model_curve, target_curves
from shapetree.retrieval import ShapeIndex, distance_matrix, search
from shapetree.tree import build_shape_tree, deform

NAMES = ["star", "square", "hand", "leaf", "triangle"]
CFG = MatchConfig.preset("general", n_points=16, n_trees=1)


@pytest.fixture(scope="module")
def curves() -> list[np.ndarray]:
    return [demo_shape(n, n_points=60) for n in NAMES]


@pytest.fixture(scope="module")
def query() -> np.ndarray:
    return deform(build_shape_tree(demo_shape("hand", n_points=60), closed=True), 0.03, rng=1)


@pytest.fixture
def saved(tmp_path: Path, curves) -> Path:
    return ShapeIndex.build(curves, NAMES, CFG).save(tmp_path / "db.stidx")


def test_round_trip(saved: Path, curves):
    ix = ShapeIndex.load(saved)
    assert len(ix) == len(NAMES) and ix.names == NAMES and ix.config == CFG
    assert ix.version == shapetree.__version__ and ix.path == saved
    for c, outline, m, ts in zip(curves, ix.outlines, ix.models, ix.targets):
        np.testing.assert_array_equal(outline, c)
        np.testing.assert_array_equal(m, model_curve(c, CFG))
        assert len(ts) == CFG.phases
        for t, want in zip(ts, target_curves(c, CFG)):
            np.testing.assert_array_equal(t, want)
    # the same configuration asked for explicitly is accepted
    assert ShapeIndex.load(saved, CFG).config == CFG
    assert ShapeIndex.load(saved, n_points=16).config == CFG


def test_as_given_samples_of_different_sizes(tmp_path: Path, curves):
    cfg = MatchConfig.preset("paper", n_points=None)
    raw = [curves[0][:40], curves[1]]
    ix = ShapeIndex.build(raw, ["a", "b"], cfg)
    back = ShapeIndex.load(ix.save(tmp_path / "raw.stidx"))
    assert [m.shape[0] for m in back.models] == [40, 60]
    np.testing.assert_array_equal(back.models[0], raw[0])


def test_add_appends_and_refuses_duplicates(saved: Path, curves):
    ix = ShapeIndex.load(saved)
    extra = [demo_shape("glyph-G", n_points=60)]
    ix.add(extra, ["G"]).save(saved)
    back = ShapeIndex.load(saved)
    assert back.names == [*NAMES, "G"]
    np.testing.assert_array_equal(back.models[-1], model_curve(extra[0], CFG))
    with pytest.raises(ShapeTreeError, match="'G' is already in the index"):
        back.add(extra, ["G"])
    with pytest.raises(ShapeTreeError, match="bad one"):
        back.add([curves[0], np.zeros((5, 2))], ["fine", "bad one"])
    assert len(back) == len(NAMES) + 1  # nothing added by a failed add
    assert ShapeIndex.build(curves[:2]).names == ["shape 0", "shape 1"]


def test_info_text(saved: Path):
    text = ShapeIndex.load(saved).info()
    assert str(saved) in text
    assert f"shapes:        {len(NAMES)}" in text
    assert "16 model points" in text and f"general preset with {CFG.describe()}" in text
    assert f"shapetree {shapetree.__version__}" in text
    assert "usable:        yes" in text


def test_search_and_distances_equal_the_curves(saved: Path, curves, query):
    ix = ShapeIndex.load(saved)
    i1, d1 = search(query, ix, workers=1)  # config=None: the index's
    i2, d2 = search(query, curves, CFG, workers=1)
    np.testing.assert_array_equal(i1, i2)
    np.testing.assert_array_equal(d1, d2)
    assert NAMES[i1[0]] == "hand"
    i3, d3 = search(query, str(saved), CFG, workers=1)  # the file name will do
    np.testing.assert_array_equal(d3, d1)
    d_ix = distance_matrix(ix, config=CFG, progress=False, workers=1)
    np.testing.assert_array_equal(d_ix, distance_matrix(curves, config=CFG, progress=False))
    # both directions (the index as models and as targets)
    sym = CFG.replace(symmetrize="min")
    ix_sym = ShapeIndex.build(curves, NAMES, sym)
    a = distance_matrix([query], ix_sym, progress=False, workers=1)
    b = distance_matrix([query], curves, sym, progress=False, workers=1)
    np.testing.assert_array_equal(a, b)


def test_fused_database_with_the_pruned_search(tmp_path: Path, curves, query):
    """A database built under the height-function fusion keeps the outlines its ``h`` is
    computed from: ``knn`` on it (file name or object) equals exhaustive search of the
    curves, indices and distances bitwise."""
    from shapetree.retrieval import knn

    fused = MatchConfig.preset("fused", n_points=16, height_points=24)
    path = ShapeIndex.build(curves, NAMES, fused).save(tmp_path / "fused.stidx")
    ref_i, ref_d = search(query, curves, fused, k=3, workers=1)
    for db in (path, ShapeIndex.load(path)):
        idx, dist = knn([query], db, k=3, workers=1)
        np.testing.assert_array_equal(idx[0], ref_i)
        np.testing.assert_array_equal(dist[0], ref_d)
    assert NAMES[ref_i[0]] == "hand"


def test_another_config_is_refused(saved: Path, curves, query):
    want = r"another matcher configuration: n_points=16 \(asked: 20\)"
    with pytest.raises(ShapeTreeError, match=want):
        ShapeIndex.load(saved, n_points=20)
    with pytest.raises(ShapeTreeError, match="another matcher configuration") as exc:
        ShapeIndex.load(saved, "paper")
    assert str(saved) in str(exc.value) and "shapetree index build" in str(exc.value)
    ix = ShapeIndex.load(saved)
    with pytest.raises(ShapeTreeError, match="another matcher configuration"):
        search(query, ix, "general")  # n_points differs
    with pytest.raises(ShapeTreeError, match="mirror=True"):
        distance_matrix(ix, mirror=False, progress=False)
    with pytest.raises(ShapeTreeError, match="another matcher configuration"):
        distance_matrix(curves, ix, MatchConfig(), progress=False)


def test_another_version_or_code_is_refused(saved: Path, monkeypatch):
    built = shapetree.__version__
    monkeypatch.setattr(shapetree, "__version__", "99.0")
    with pytest.raises(ShapeTreeError) as exc:
        ShapeIndex.load(saved)
    msg = str(exc.value)
    assert f"built by shapetree {built}, this is shapetree 99.0" in msg
    assert str(saved) in msg and "shapetree index build" in msg
    assert "usable:        no" in ShapeIndex._read(saved).info()
    monkeypatch.undo()

    import shapetree.retrieval._index as mod

    real = mod._current()
    loaded = ShapeIndex.load(saved)
    monkeypatch.setattr(mod, "_current", lambda: (real[0], "0" * 64))
    with pytest.raises(ShapeTreeError, match="built by other code of shapetree"):
        ShapeIndex.load(saved)
    with pytest.raises(ShapeTreeError, match="built by other code"):
        loaded.add([demo_shape("star")], ["x"])  # no mixing of old and new samples
    monkeypatch.undo()
    assert ShapeIndex.load(saved).names == NAMES


def _members(path: Path) -> dict[str, np.ndarray]:
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def _write(path: Path, members: dict[str, np.ndarray]) -> None:
    with open(path, "wb") as fh:
        np.savez(fh, **members)


def test_flipped_bytes_and_truncation_are_detected(saved: Path, tmp_path: Path):
    data = saved.read_bytes()
    bad = tmp_path / "bad.stidx"
    positions = sorted({*range(0, len(data), max(1, len(data) // 60)), len(data) - 1})
    undetected = []
    for pos in positions:
        flipped = bytearray(data)
        flipped[pos] ^= 0x5A
        bad.write_bytes(bytes(flipped))
        try:
            ShapeIndex.load(bad)
        except ShapeTreeError as exc:
            assert str(bad) in str(exc)
        else:
            # a zip file has bytes no reader looks at (e.g. a timestamp); the data must survive
            again = ShapeIndex.load(bad)
            if again.names != NAMES or not all(
                np.array_equal(a, b) for a, b in zip(again.models, ShapeIndex.load(saved).models)
            ):
                undetected.append(pos)
    assert not undetected
    for cut in (0, 10, len(data) // 2, len(data) - 1):
        bad.write_bytes(data[:cut])
        with pytest.raises(ShapeTreeError, match="damaged or not a shape index") as exc:
            ShapeIndex.load(bad)
        assert str(bad) in str(exc.value)
    bad.write_text("x,y\n0,0\n")
    with pytest.raises(ShapeTreeError, match="damaged or not a shape index"):
        ShapeIndex.load(bad)
    np.save(bad.with_suffix(".npy"), np.zeros((3, 2)))  # a plain array, not an archive
    bad.with_suffix(".npy").replace(bad)
    with pytest.raises(ShapeTreeError, match="not a zip archive"):
        ShapeIndex.load(bad)
    _write(bad, {"x": np.zeros(3)})  # an .npz, but not an index
    with pytest.raises(ShapeTreeError, match="no shapetree index header"):
        ShapeIndex.load(bad)
    with pytest.raises(ShapeTreeError, match="no such shape index"):
        ShapeIndex.load(tmp_path / "missing.stidx")


def test_checksums_catch_what_the_zip_does_not(saved: Path, tmp_path: Path):
    members = _members(saved)
    bad = tmp_path / "bad.stidx"
    changed = dict(members, model_xy=members["model_xy"] + 1e-12)  # a valid zip, other data
    _write(bad, changed)
    with pytest.raises(ShapeTreeError, match="checksum mismatch in model_xy"):
        ShapeIndex.load(bad)
    header = json.loads(members["header"].tobytes())
    header["names"][0] = "renamed"  # header edited without its checksum
    hb = np.frombuffer(json.dumps(header).encode(), np.uint8)
    _write(bad, dict(members, header=hb))
    with pytest.raises(ShapeTreeError, match="header checksum mismatch"):
        ShapeIndex.load(bad)
    header["format_version"] = 2  # a newer layout, consistently checksummed
    hb = np.frombuffer(json.dumps(header).encode(), np.uint8)
    hs = np.frombuffer(hashlib.sha256(hb.tobytes()).hexdigest().encode(), np.uint8)
    _write(bad, dict(members, header=hb, header_sha256=hs))
    with pytest.raises(ShapeTreeError, match="format version 2, this shapetree reads version 1"):
        ShapeIndex.load(bad)


def test_save_is_atomic(saved: Path, curves, monkeypatch):
    before = saved.read_bytes()
    ix = ShapeIndex.build(curves[:2], ["a", "b"], CFG)

    def broken(fh, **arrays):
        fh.write(b"PK\x03\x04 half a file")
        raise RuntimeError("disk full")

    monkeypatch.setattr(np, "savez", broken)
    with pytest.raises(RuntimeError, match="disk full"):
        ix.save(saved)
    with pytest.raises(RuntimeError, match="disk full"):
        ix.save(saved.parent / "new.stidx")
    monkeypatch.undo()
    assert saved.read_bytes() == before
    assert sorted(p.name for p in saved.parent.iterdir()) == ["db.stidx"]  # no temp file left


# ---------------------------------------------------------------- command line


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def folder(tmp_path_factory, curves) -> Path:
    d = tmp_path_factory.mktemp("shapes")
    for name, c in zip(NAMES, curves):
        np.savetxt(d / f"{name}.csv", c, delimiter=",")
    return d


def _ranking(out: str) -> list[tuple[str, str]]:
    rows = [ln.split() for ln in out.splitlines() if ln.strip()[:1].isdigit()]
    return [(r[1], r[2]) for r in rows]


FLAGS = ["--n-points", "16", "--n-trees", "1"]


def test_cli_build_add_info_search_distances(capsys, folder: Path, tmp_path: Path):
    db = tmp_path / "db.stidx"
    first = [folder / f"{n}.csv" for n in NAMES[:3]]
    code, out, err = run(capsys, "index", "build", *first, "-o", db, *FLAGS, "--no-progress")
    assert code == 0, err
    assert "3 shapes" in out and db.exists()
    code, out, err = run(capsys, "index", "add", db, folder, "--no-progress")
    assert code == 0, err
    assert "added 2 shapes; 5 in" in out and "skipped 3 shape(s) already" in err
    code, out, err = run(capsys, "index", "info", db, "--names")
    assert code == 0, err
    assert "shapes:        5" in out and "n_points=16" in out and "leaf.csv" in out

    q = folder / "hand.csv"
    code, out_db, err = run(capsys, "search", q, db, "-k", "5", "--no-progress")
    assert code == 0, err
    code, out_files, err = run(capsys, "search", q, folder, "-k", "5", *FLAGS, "--no-progress")
    assert code == 0, err
    assert _ranking(out_db) == _ranking(out_files) and _ranking(out_db)[0][1] == "hand.csv"
    code, _, err = run(capsys, "search", q, db, "--n-points", "16", "--no-progress")
    assert code == 0, err  # agreeing flags are fine

    d1, d2 = tmp_path / "D1.npz", tmp_path / "D2.npz"
    code, _, err = run(capsys, "distances", db, "-o", d1, "--no-cache", "--no-progress")
    assert code == 0, err
    code, _, err = run(capsys, "distances", folder, "-o", d2, *FLAGS, "--no-cache", "--no-progress")
    assert code == 0, err
    z1, z2 = np.load(d1), np.load(d2)
    order = [list(z2["names"]).index(n) for n in z1["names"]]
    np.testing.assert_array_equal(z1["D"], z2["D"][np.ix_(order, order)])
    assert json.loads(str(z1["config"]))["database"] == str(db)


def test_cli_refusals(capsys, folder: Path, tmp_path: Path):
    db = tmp_path / "db.stidx"
    assert run(capsys, "index", "build", folder, "-o", db, *FLAGS, "--no-progress")[0] == 0
    code, _, err = run(capsys, "search", folder / "hand.csv", db, "--n-points", "20")
    assert code == 2 and "another matcher configuration: n_points=16 (asked: 20)" in err
    code, _, err = run(capsys, "distances", db, "-o", tmp_path / "D.npz", "--preset", "paper")
    assert code == 2 and "another matcher configuration" in err
    code, _, err = run(capsys, "search", folder / "hand.csv", db, folder)
    assert code == 2 and "must be given alone" in err
    code, _, err = run(capsys, "index", "build", folder, "-o", tmp_path / "db.npz")
    assert code == 2 and "must end in .stidx" in err
    code, _, err = run(capsys, "index", "add", db, db)
    assert code == 2 and "only shape files and folders can be added" in err
    data = bytearray(db.read_bytes())
    data[len(data) // 2] ^= 0xFF
    db.write_bytes(bytes(data))
    for argv in (["index", "info", db], ["search", folder / "hand.csv", db]):
        code, _, err = run(capsys, *argv)
        assert code == 2 and f"{db}: damaged or not a shape index" in err


def test_cli_rebuild_from_a_database(capsys, folder: Path, tmp_path: Path):
    old, new = tmp_path / "old.stidx", tmp_path / "new.stidx"
    assert run(capsys, "index", "build", folder, "-o", old, *FLAGS, "--no-progress")[0] == 0
    code, _, err = run(capsys, "index", "build", old, "--n-points", "12", "-o", new)
    assert code == 0, err
    a, b = ShapeIndex.load(old), ShapeIndex.load(new)
    assert b.names == a.names and b.config == MatchConfig(n_points=12)
    for x, y in zip(a.outlines, b.outlines):
        np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("sub", ["build", "add", "info"])
def test_cli_help(capsys, sub):
    code, out, _ = run(capsys, "index", sub, "--help")
    assert code == 0 and "examples:" in out and "shapetree index" in out


def test_concurrent_adds_keep_every_shape(folder: Path, tmp_path: Path):
    """Two ``index add`` processes on one database at once: the lock queues them, and
    the database ends with the shapes of both (none silently dropped)."""
    import subprocess
    import sys

    files = sorted(folder.iterdir())
    db = tmp_path / "db.stidx"
    base = [sys.executable, "-m", "shapetree.cli"]
    opts = ["--n-points", "16", "--n-trees", "1", "--no-progress"]
    subprocess.run([*base, "index", "build", str(files[0]), "-o", str(db), *opts], check=True)
    halves = [files[1::2], files[2::2]]
    procs = [
        subprocess.Popen(
            [*base, "index", "add", str(db), *map(str, h), "--no-progress"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        for h in halves
    ]
    for p in procs:
        _, err = p.communicate(timeout=300)
        assert p.returncode == 0, err.decode()
    ix = ShapeIndex.load(db)
    assert sorted(Path(n).name for n in ix.names) == sorted(f.name for f in files)
