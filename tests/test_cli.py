"""The ``shapetree`` command line, run in-process (and once as a subprocess)."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image, ImageDraw

from shapetree import __version__
from shapetree.cli import main
from shapetree.curves import load_curve
from shapetree.matching import match

COMMAND_OPTIONS = {
    "match": [
        "--preset",
        "--n-points",
        "--weight",
        "--occlusion",
        "--n-trees",
        "--split",
        "--mirror",
        "--phases",
        "--open",
        "--plot",
        "--json",
    ],
    "tree": ["--n-points", "--split", "--levels", "--output"],
    "deform": ["--n-points", "--scale", "--count", "--seed", "--output"],
    "demo": ["--output", "--query", "--preset", "--seed", "--list"],
    "datasets": ["fetch", "list"],
    "evaluate": ["--json", "--out", "--param", "kimia99", "mpeg7", "swedish_leaf", "ethz"],
    "detect": ["--edges", "--output", "--json", "-k"],
    "search": ["-k", "--plot", "--json", "--preset", "--n-points", "--n-trees", "--mirror"],
    "distances": ["--output", "--csv", "--symmetrize", "--cache", "--no-cache", "--band"],
    "index": ["build", "add", "info"],
}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("shapes")
    t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    np.savetxt(
        d / "circle.csv", np.c_[np.cos(t), np.sin(t)], delimiter=",", header="x,y", comments=""
    )
    np.savetxt(
        d / "ellipse.csv",
        np.c_[2 * np.cos(t), 0.8 * np.sin(t) + 0.1 * np.cos(3 * t)],
        delimiter=",",
    )
    im = Image.new("L", (120, 100), 255)
    draw = ImageDraw.Draw(im)
    draw.polygon([(20, 80), (60, 15), (100, 80), (60, 60)], fill=0)  # an arrow head
    im.save(d / "arrow.png")
    Image.new("L", (50, 50), 255).save(d / "blank.png")
    (d / "nan.csv").write_text("x,y\n0,0\n1,nan\n2,3\n3,1\n")
    (d / "two.csv").write_text("0,0\n1,1\n")
    return d


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def printed_cost(out: str) -> float:
    m = re.search(r"^cost: (\S+)$", out, flags=re.M)
    assert m, out
    return float(m.group(1))


@pytest.mark.parametrize("command", sorted(COMMAND_OPTIONS))
def test_every_command_has_help(capsys, command):
    code, out, _ = run(capsys, command, "--help")
    assert code == 0
    assert "examples:" in out
    for opt in COMMAND_OPTIONS[command]:
        assert opt in out, f"{command} --help does not mention {opt}"


def test_main_help_and_version(capsys):
    code, out, _ = run(capsys, "--help")
    assert code == 0
    for command in COMMAND_OPTIONS:
        assert command in out
    code, out, _ = run(capsys, "--version")
    assert code == 0 and __version__ in out
    code, _, err = run(capsys)
    assert code == 2 and "COMMAND" in err


def test_module_entry_point_subprocess():
    proc = subprocess.run(
        [sys.executable, "-m", "shapetree.cli", "--help"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    assert "usage: shapetree" in proc.stdout and "match" in proc.stdout


def test_match_point_files_prints_the_library_cost(capsys, files, tmp_path):
    a, b = files / "circle.csv", files / "ellipse.csv"
    code, out, err = run(capsys, "match", a, b, "--n-points", 40, "--json", tmp_path / "m.json")
    assert code == 0, err
    pa, _ = load_curve(a, closed=True)
    pb, _ = load_curve(b, closed=True)
    expected = match(pa, pb, n_points=40).cost
    assert printed_cost(out) == pytest.approx(expected, rel=1e-10, abs=1e-14)
    doc = json.loads((tmp_path / "m.json").read_text())
    assert doc["cost"] == pytest.approx(expected, rel=1e-12)
    assert len(doc["a_to_b"]) == 40 and doc["closed"] is True


def test_match_options_are_passed_through(capsys, files):
    a, b = files / "circle.csv", files / "ellipse.csv"
    code, out, _ = run(
        capsys,
        "match",
        a,
        b,
        "--n-points",
        30,
        "--weight",
        2,
        "--n-trees",
        2,
        "--split",
        "best",
        "--occlusion",
        0.3,
        "--no-mirror",
        "--band",
        "none",
    )
    assert code == 0
    pa, _ = load_curve(a, closed=True)
    pb, _ = load_curve(b, closed=True)
    opts = dict(n_points=30, weight=2.0, n_trees=2, split="best", occlusion=0.3)
    res = match(pa, pb, mirror=False, band=None, **opts)
    assert printed_cost(out) == pytest.approx(res.cost, rel=1e-10, abs=1e-14)
    assert "shape-trees: cost is the best 2" in out and "correspondence from the cheapest, #" in out
    code, out, _ = run(
        capsys, "match", a, b, "--n-points", 30, "--n-trees", 3, "--tree-combine", "mean"
    )
    assert code == 0 and "shape-trees: cost is the mean of 3" in out
    res = match(pa, pb, n_points=30, n_trees=3, tree_combine="mean")
    assert printed_cost(out) == pytest.approx(res.cost, rel=1e-10)
    code, out, _ = run(capsys, "match", a, b, "--n-points", 20, "--open")
    pa, _ = load_curve(a, closed=False)
    pb, _ = load_curve(b, closed=False)
    want = match(pa, pb, closed=False, n_points=20).cost
    assert printed_cost(out) == pytest.approx(want, rel=1e-10)


def test_match_image_with_plot(capsys, files, tmp_path):
    png = tmp_path / "out" / "match.png"
    code, out, err = run(
        capsys,
        "match",
        files / "arrow.png",
        files / "ellipse.csv",
        "--n-points",
        36,
        "--plot",
        png,
    )
    assert code == 0, err
    pa, _ = load_curve(files / "arrow.png", closed=True)
    pb, _ = load_curve(files / "ellipse.csv", closed=True)
    want = match(pa, pb, n_points=36).cost
    assert printed_cost(out) == pytest.approx(want, rel=1e-10, abs=1e-14)
    assert str(png) in out
    with Image.open(png) as im:
        assert im.format == "PNG"
        assert im.width >= 400 and im.height >= 200
        assert len(np.unique(np.asarray(im.convert("L")))) > 10  # not a blank picture
    assert sorted(p.name for p in png.parent.iterdir()) == ["match.png"]


def test_match_demo_shapes_rank_a_rotated_copy_first(capsys, tmp_path):
    """A glyph costs far less against a rotated, rescaled copy of itself than against
    another glyph (the cost is similarity-invariant up to sampling)."""
    from shapetree.demo import demo_shape

    g = demo_shape("glyph-G", n_points=200)
    c, s = np.cos(0.7), np.sin(0.7)
    np.savetxt(tmp_path / "g.csv", 2.5 * g @ np.array([[c, -s], [s, c]]) + 3.0, delimiter=",")
    code, out, _ = run(capsys, "match", "demo:G", tmp_path / "g.csv")
    assert code == 0
    own = printed_cost(out)
    code, out, _ = run(capsys, "match", "demo:G", "demo:glyph-S")
    assert code == 0
    assert own < 0.1 * printed_cost(out)


@pytest.mark.parametrize(
    ("name", "words"),
    [
        ("missing.csv", ["missing.csv", "not found"]),
        ("missing.png", ["missing.png", "not found"]),
        ("blank.png", ["blank.png", "blank"]),
        ("nan.csv", ["nan.csv", "NaN"]),
        ("two.csv", ["two.csv", "fewer than 3"]),
    ],
)
def test_bad_input_is_one_line_exit_2(capsys, files, name, words):
    code, out, err = run(capsys, "match", files / name, files / "circle.csv")
    assert code == 2
    assert err.startswith("shapetree: error: ")
    assert err.count("\n") == 1, err
    assert "Traceback" not in err
    for w in words:
        assert w in err


@pytest.mark.parametrize(
    "argv",
    [
        ["match", "demo:G", "demo:S", "--plot", "out.xyz"],
        ["match", "demo:nosuch", "demo:S"],
        ["tree", "demo:G", "-o", "tree.gif"],
        ["deform", "demo:G", "--open"],
    ],
)
def test_bad_arguments_are_one_line_exit_2(capsys, tmp_path, monkeypatch, argv):
    monkeypatch.chdir(tmp_path)
    code, _, err = run(capsys, *argv)
    assert code == 2
    assert err.startswith("shapetree: error: ") and err.count("\n") == 1, err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "argv",
    [
        ["match", "a", "b", "--n-points", "2"],
        ["match", "a", "b", "--phases", "x"],
        ["match", "a", "b", "--preset", "nosuch"],
        ["deform", "x", "--count", "0"],
        ["match", "a", "b", "--weight", "nan"],
    ],
)
def test_usage_errors_exit_2(capsys, argv):
    code, _, err = run(capsys, *argv)
    assert code == 2 and "Traceback" not in err and "error:" in err


def test_tree_and_deform_write_pictures(capsys, files, tmp_path):
    out = tmp_path / "tree.png"
    code, text, _ = run(capsys, "tree", files / "arrow.png", "--n-points", 24, "-o", out)
    assert code == 0 and str(out) in text
    with Image.open(out) as im:
        assert im.format == "PNG" and im.width > 300
    out = tmp_path / "deform.png"
    code, text, _ = run(
        capsys,
        "deform",
        "demo:star",
        "--n-points",
        32,
        "--scale",
        "0.02",
        "0.05",
        "--count",
        3,
        "-o",
        out,
    )
    assert code == 0 and str(out) in text
    with Image.open(out) as im:
        assert im.format == "PNG" and im.width > 300


def test_default_output_names(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert run(capsys, "tree", "demo:leaf", "--n-points", 20)[0] == 0
    assert run(capsys, "deform", "demo:leaf", "--n-points", 20, "--count", 1)[0] == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["leaf-deform.png", "leaf-tree.png"]


def test_demo_ranks_deformed_copy_first_and_writes_pictures(capsys, tmp_path):
    out = tmp_path / "demo"
    code, text, err = run(capsys, "demo", "-o", out, "--no-progress")
    assert code == 0, err
    rows = re.findall(r"^\s+(\d+)\s+([0-9.]+)\s+(\S+)\s+(.*)$", text, flags=re.M)
    assert len(rows) >= 10
    costs = [float(r[1]) for r in rows]
    assert costs == sorted(costs)
    assert rows[0][2] == "G~1" or rows[0][2] == "G~2"
    assert "deformed copy of the query" in rows[0][3]
    assert "deformed copy" not in " ".join(r[3] for r in rows[2:])
    assert "rank first" in text and "NOT" not in text
    names = {
        "demo_match.png",
        "demo_ranking.png",
        "demo_occlusion.png",
        "demo_tree.png",
        "demo_deform.png",
        "demo_detection.png",
    }
    assert {p.name for p in out.iterdir()} == names
    for name in names:
        assert str(out / name) in text
        with Image.open(out / name) as im:
            assert im.format == "PNG" and im.width > 400


def test_demo_list(capsys):
    code, out, _ = run(capsys, "demo", "--list")
    assert code == 0 and "glyph-G" in out and "hand" in out


def test_datasets_lists(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("SHAPETREE_DATA", str(tmp_path))
    code, out, _ = run(capsys, "datasets")
    assert code == 0 and "mpeg7" in out and str(tmp_path) in out
    assert run(capsys, "datasets", "list")[0] == 0


def test_datasets_fetch_errors_are_one_line(capsys, tmp_path):
    # no checksum known for a custom URL, and not --insecure: refused before any download
    code, _, err = run(
        capsys,
        "datasets",
        "fetch",
        "mpeg7",
        "--dest",
        tmp_path,
        "--url",
        "file:///nonexistent/archive.zip",
        "--no-progress",
    )
    assert code == 2 and err.startswith("shapetree: error: ") and err.count("\n") == 1
    assert "checksum" in err
    assert list(tmp_path.iterdir()) == []


def test_evaluate_without_data_is_one_line(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("SHAPETREE_DATA", str(tmp_path / "none"))
    monkeypatch.setenv("SHAPETREE_CACHE", str(tmp_path / "cache"))
    code, _, err = run(capsys, "evaluate", "kimia99", "--no-progress")
    assert code == 2 and err.startswith("shapetree: error: ") and err.count("\n") == 1, err


def test_detect_missing_files_is_one_line(capsys, tmp_path):
    code, _, err = run(capsys, "detect", tmp_path / "model.png", tmp_path / "image.jpg")
    assert code == 2 and err.startswith("shapetree: error: ") and err.count("\n") == 1, err


def test_evaluate_passes_options_to_retrieval(capsys, monkeypatch, tmp_path):
    import shapetree.retrieval as retrieval

    seen = {}

    def fake_evaluate(name, config, **kwargs):
        seen.update(kwargs, name=name, config=config)
        return {"dataset": name}

    monkeypatch.setattr(retrieval, "evaluate", fake_evaluate)
    code, _, err = run(
        capsys,
        "evaluate",
        "mpeg7",
        "--json",
        tmp_path / "r.json",
        "--no-progress",
        "--n-points",
        "30",
        "--no-mirror",
        "--workers",
        "3",
        "-k",
        "20",
        "--param",
        "band=1.5",
        "--preset",
        "paper",
    )
    assert code == 0, err
    assert seen["name"] == "mpeg7" and seen["json_path"] == str(tmp_path / "r.json")
    assert seen["config"] == "paper"
    assert seen["progress"] is False
    assert seen["n_points"] == 30 and seen["mirror"] is False and seen["band"] == 1.5
    assert seen["workers"] == 3 and seen["k"] == 20
    assert "weight" not in seen  # untouched options keep the preset's value


def test_evaluate_caches_by_default_so_runs_resume(capsys, monkeypatch, tmp_path):
    import shapetree.retrieval as retrieval

    seen: list = []
    monkeypatch.setattr(retrieval, "evaluate", lambda name, cfg, **kw: seen.append(kw) or {})
    monkeypatch.setenv("SHAPETREE_CACHE", str(tmp_path / "c"))
    assert run(capsys, "evaluate", "kimia99", "--no-progress")[0] == 0
    assert seen[-1]["cache_dir"] == str(tmp_path / "c" / "distances" / "kimia99")
    assert run(capsys, "evaluate", "kimia99", "--no-progress", "--no-cache")[0] == 0
    assert seen[-1]["cache_dir"] is None
    assert run(capsys, "evaluate", "kimia99", "--cache-dir", str(tmp_path / "x"))[0] == 0
    assert seen[-1]["cache_dir"] == str(tmp_path / "x")


def test_evaluate_ethz_and_detect_are_wired(capsys, monkeypatch, tmp_path):
    import shapetree.detection as detection

    calls = {}

    def fake_ethz(data_dir, **kwargs):
        calls["ethz"] = (data_dir, kwargs)
        return {"overlap_20": {"dr_fppi_0.4": {"mean": 0.5}}}

    class Det:
        cost, score, coverage, bbox = 0.25, -0.2875, 0.9, (1.0, 2.0, 30.0, 40.0)

    def fake_detect(model, image, **kwargs):
        calls["detect"] = (model, image, kwargs)
        return [Det()]

    monkeypatch.setattr(detection, "evaluate_ethz", fake_ethz)
    monkeypatch.setattr(detection, "detect_to_files", fake_detect)
    code, out, err = run(
        capsys,
        "evaluate",
        "ethz",
        "--data",
        tmp_path,
        "--classes",
        "swans",
        "-k",
        "3",
        "--workers",
        "1",
        "--param",
        "tau=10",
    )
    assert code == 0, err
    data_dir, kw = calls["ethz"]
    assert data_dir == str(tmp_path) and kw["classes"] == ["swans"] and kw["k"] == 3
    assert kw["workers"] == 1 and kw["params"].tau == 10 and kw["progress"] is True
    assert "mean: 0.5" in out
    code, out, err = run(
        capsys,
        "detect",
        "m.png",
        "i.jpg",
        "--edges",
        "e.png",
        "-k",
        "2",
        "-o",
        tmp_path / "d.png",
        "--json",
        tmp_path / "d.json",
    )
    assert code == 0, err
    model, image, kw = calls["detect"]
    assert (model, image, kw["edges_path"], kw["k"]) == ("m.png", "i.jpg", "e.png", 2)
    assert kw["out_png"] == str(tmp_path / "d.png") and kw["out_json"] == str(tmp_path / "d.json")
    assert "0.2500" in out and "-0.2875" in out and "(1, 2, 30, 40)" in out
