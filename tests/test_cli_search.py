"""``shapetree search`` and ``shapetree distances`` on folders the tests make themselves."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from shapetree.cli import main
from shapetree.demo import demo_shape
from shapetree.demo._run import similarity
from shapetree.tree import build_shape_tree, deform

NAMES = ["star", "square", "triangle", "hand", "leaf", "glyph-G"]


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """Six demo outlines and a deformed, rotated, rescaled copy of each, as point files."""
    d = tmp_path_factory.mktemp("db")
    for i, name in enumerate(NAMES):
        pts = demo_shape(name, n_points=60)
        np.savetxt(d / f"{name}.csv", pts, delimiter=",")
        copy = deform(build_shape_tree(pts, closed=True), 0.03, rng=i)
        copy = similarity(copy, angle=0.7 + i, scale=2.5, shift=(10.0, -4.0), roll=7)
        np.save(d / f"{name}-copy.npy", copy)
    (d / "notes.md").write_text("not a shape, ignored by folder expansion\n")
    return d


@pytest.mark.parametrize("name", ["star", "hand", "glyph-G"])
def test_search_ranks_the_deformed_copy_first(capsys, folder: Path, tmp_path: Path, name: str):
    out_json = tmp_path / "r.json"
    out_png = tmp_path / "r.png"
    code, out, err = run(
        capsys,
        "search",
        folder / f"{name}.csv",
        folder,
        "-k",
        "3",
        "--n-points",
        "32",
        "--n-trees",
        "1",
        "--json",
        out_json,
        "--plot",
        out_png,
        "--no-progress",
    )
    assert code == 0, err
    rows = [ln.split() for ln in out.splitlines() if ln.strip()[:1].isdigit()]
    assert [r[2] for r in rows[:2]] == [f"{name}.csv", f"{name}-copy.npy"]
    assert float(rows[0][1]) == 0.0 and float(rows[1][1]) > 0.0
    rec = json.loads(out_json.read_text())
    assert len(rec["ranking"]) == 2 * len(NAMES)  # the full ranking, notes.md skipped
    dist = [r["distance"] for r in rec["ranking"]]
    assert dist == sorted(dist)
    assert rec["config"]["n_points"] == 32 and rec["preset"] == "general"
    assert out_png.stat().st_size > 5_000


def test_distances_matrix_resumes_and_writes_csv(capsys, folder: Path, tmp_path: Path):
    args = ["distances", folder, "--n-points", "24", "--n-trees", "1", "--no-progress"]
    args += ["--cache", tmp_path / "cache"]
    code, out, err = run(capsys, *args, "-o", tmp_path / "D.npz", "--csv", tmp_path / "D.csv")
    assert code == 0, err
    z = np.load(tmp_path / "D.npz")
    d, names = z["D"], [Path(n).name for n in z["names"]]
    n = 2 * len(NAMES)
    assert d.shape == (n, n) and len(names) == n
    assert np.allclose(np.diag(d), 0.0, atol=1e-12)
    assert json.loads(str(z["config"]))["config"]["n_points"] == 24
    # every shape's nearest other shape is its deformed copy (or the copy's original)
    off = d + np.diag(np.full(n, np.inf))
    for i, nm in enumerate(names):
        stem = nm.split(".")[0].removesuffix("-copy")
        assert names[int(np.argmin(off[i]))].split(".")[0].removesuffix("-copy") == stem
    lines = (tmp_path / "D.csv").read_text().splitlines()
    assert len(lines) == n + 1 and lines[0].split(",")[1:] == names
    assert np.allclose(np.array([ln.split(",")[1:] for ln in lines[1:]], float), d, rtol=1e-7)
    # second run: every block from the cache, same matrix
    code, _, err = run(capsys, *args, "-o", tmp_path / "D2.npz")
    assert code == 0, err
    assert np.array_equal(np.load(tmp_path / "D2.npz")["D"], d)


def test_bad_shapes_are_listed_or_skipped(capsys, folder: Path, tmp_path: Path):
    db = tmp_path / "db"
    db.mkdir()
    for f in list(folder.glob("*.csv"))[:3]:
        (db / f.name).write_bytes(f.read_bytes())
    (db / "broken.png").write_bytes(b"not an image")
    (db / "nan.csv").write_text("0,0\n1,nan\n2,0\n")
    query = folder / "star.csv"
    code, out, err = run(capsys, "search", query, db, "--n-points", "20", "--no-progress")
    assert code == 2 and out == ""
    assert "2 of 5 shapes could not be read" in err
    assert "broken.png" in err and "nan.csv" in err and "--skip-bad" in err
    assert len(err.strip().splitlines()) == 1
    code, out, err = run(
        capsys, "search", query, db, "--n-points", "20", "--no-progress", "--skip-bad"
    )
    assert code == 0 and "skipped 2 unreadable" in err
    assert "3 nearest of 3 shapes" in out or "of 3 shapes" in out


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["search", "demo:star", "{tmp}/missing"], "no such file or folder"),
        (["search", "demo:star", "{tmp}/empty"], "no shape files"),
        (["distances", "demo:star", "demo:square", "-o", "{tmp}/D.txt"], "must be a .npz"),
        (["distances", "demo:star", "-o", "{tmp}/D.npz"], "at least 2 shapes"),
    ],
)
def test_usage_problems_are_one_line(capsys, tmp_path: Path, argv: list[str], words: str):
    (tmp_path / "empty").mkdir()
    code, out, err = run(capsys, *[a.format(tmp=tmp_path) for a in argv], "--no-progress")
    assert code == 2
    assert words in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "D.npz").exists() and not (tmp_path / "D.txt").exists()


def test_search_with_smoothing(capsys, folder: Path, tmp_path: Path):
    out_json = tmp_path / "s.json"
    args = ["search", folder / "hand.csv", folder, "--n-points", "32", "--n-trees", "1"]
    code, out, err = run(capsys, *args, "--smooth", "0.005", "--json", out_json, "--no-progress")
    assert code == 0, err
    rec = json.loads(out_json.read_text())
    assert rec["config"]["smooth"] == 0.005
    assert [r["shape"].split("/")[-1] for r in rec["ranking"][:2]] == ["hand.csv", "hand-copy.npy"]
    # smoothing changes the numbers (the query matches its own smoothed self at 0)
    code, _, _ = run(capsys, *args, "--json", tmp_path / "p.json", "--no-progress")
    plain = json.loads((tmp_path / "p.json").read_text())["ranking"]
    assert rec["ranking"][1]["distance"] != plain[1]["distance"]
    assert abs(rec["ranking"][0]["distance"]) < 1e-12


def test_distances_bad_csv_path_writes_nothing(capsys, folder: Path, tmp_path: Path):
    (tmp_path / "csvdir").mkdir()
    args = ["distances", folder, "-o", tmp_path / "D.npz", "--csv", tmp_path / "csvdir"]
    code, out, err = run(capsys, *args, "--no-progress", "--no-cache")
    assert code == 2 and "is a directory" in err
    assert not (tmp_path / "D.npz").exists()


def test_distances_neighbours_equal_the_full_matrix(capsys, folder: Path, tmp_path: Path):
    """``--neighbours K``: each row's K nearest of the full matrix, the same numbers."""
    args = ["distances", folder, "--n-points", "24", "--n-trees", "1", "--no-progress"]
    args += ["--no-cache"]
    code, _, err = run(capsys, *args, "-o", tmp_path / "D.npz")
    assert code == 0, err
    d = np.load(tmp_path / "D.npz")["D"]
    out = tmp_path / "NN.npz"
    code, text, err = run(
        capsys, *args, "-o", out, "--neighbours", "3", "--csv", tmp_path / "n.csv"
    )
    assert code == 0, err
    assert "nearest each" in text + err and "skipped by the lower bound" in text + err
    z = np.load(out)
    order = np.argsort(d, axis=1, kind="stable")[:, :3]
    np.testing.assert_array_equal(z["indices"], order)
    np.testing.assert_array_equal(z["distances"], np.take_along_axis(d, order, axis=1))
    meta = json.loads(str(z["config"]))
    assert meta["neighbours"]["k"] == 3 and 0 <= meta["neighbours"]["skipped"] < 1
    lines = (tmp_path / "n.csv").read_text().splitlines()
    assert lines[0] == "shape,rank,neighbour,distance" and len(lines) == 1 + 3 * d.shape[0]
    bad = [*args, "--n-points", "none", "--phases", "1", "-o", out, "--neighbours", "2"]
    code, _, err = run(capsys, *bad)
    assert code != 0 and "--n-points" in err and "Traceback" not in err


def test_distances_on_a_local_dask_cluster_equal_the_threads(capsys, folder, tmp_path):
    """``--dask local:2``: two worker processes, bitwise the threaded matrix; a cache
    written by the cluster run is read back by a threaded run."""
    pytest.importorskip("distributed")
    args = ["distances", folder, "--n-points", "16", "--n-trees", "1", "--no-progress"]
    code, _, err = run(capsys, *args, "--no-cache", "-o", tmp_path / "T.npz")
    assert code == 0, err
    cache = tmp_path / "cache"
    code, _, err = run(
        capsys, *args, "--cache", cache, "--dask", "local:2", "-o", tmp_path / "K.npz"
    )
    assert code == 0, err
    d = np.load(tmp_path / "T.npz")["D"]
    assert np.array_equal(np.load(tmp_path / "K.npz")["D"], d)
    assert list(cache.rglob("*.blk"))
    code, _, err = run(capsys, *args, "--cache", cache, "-o", tmp_path / "R.npz")
    assert code == 0, err
    assert np.array_equal(np.load(tmp_path / "R.npz")["D"], d)
    code, _, err = run(capsys, *args, "--dask", "local:zero", "-o", tmp_path / "X.npz")
    assert code != 0 and "local:N" in err and "Traceback" not in err
    assert not (tmp_path / "X.npz").exists()
    # the pruned search on the cluster: bitwise the threaded search, which is the full
    # matrix's 2 smallest per row
    nn = ["--neighbours", "2", "--no-cache"]
    code, _, err = run(capsys, *args, *nn, "-o", tmp_path / "NT.npz")
    assert code == 0, err
    code, _, err = run(capsys, *args, *nn, "--dask", "local:2", "-o", tmp_path / "ND.npz")
    assert code == 0, err
    nt, nd = np.load(tmp_path / "NT.npz"), np.load(tmp_path / "ND.npz")
    assert np.array_equal(nd["indices"], nt["indices"])
    assert np.array_equal(nd["distances"], nt["distances"])
    assert np.allclose(nt["distances"], np.sort(d, axis=1)[:, :2], rtol=1e-6, atol=0)
