"""``shapetree detect MODEL IMAGES...`` on scenes the project draws (known answers)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from shapetree import ShapeTreeError
from shapetree.cli import main
from shapetree.demo._scene import box_iou, detection_scene
from shapetree.detection import DetectParams
from shapetree.detection._photos import collect_images, detect_images, natural_key

SCENE = dict(size=(150, 190), object_size=90.0, n_distractors=5)


@pytest.fixture(scope="module")
def photos(tmp_path_factory) -> dict:
    """Two scenes with a star, a bad file, an empty file, a 2x2 image and an SVG model."""
    d = tmp_path_factory.mktemp("photos")
    imgs = d / "imgs"
    imgs.mkdir()
    boxes = {}
    for seed in (1, 2):
        sc = detection_scene("star", seed=seed, **SCENE)
        name = f"scene{seed}.png"
        Image.fromarray(np.round(sc.image * 255).astype(np.uint8)).save(imgs / name)
        boxes[name] = sc.box
    (imgs / "broken.jpg").write_bytes(b"not an image")
    (imgs / "empty.png").write_bytes(b"")
    Image.new("L", (2, 2)).save(imgs / "tiny.png")
    (imgs / "notes.txt").write_text("not an image extension: ignored in a folder")
    pts = sc.model * 100.0
    path = "M " + " L ".join(f"{x:.3f} {y:.3f}" for x, y in pts) + " Z"
    svg = d / "star.svg"
    svg.write_text(f'<svg xmlns="http://www.w3.org/2000/svg"><path d="{path}"/></svg>')
    return {"dir": d, "imgs": imgs, "boxes": boxes, "model": svg}


def test_collect_images_natural_order_and_errors(tmp_path: Path) -> None:
    for name in ("img10.png", "img2.PNG", "img1.jpg", "readme.md"):
        (tmp_path / name).write_bytes(b"")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "img3.png").write_bytes(b"")
    got = [p.name for p in collect_images([tmp_path])]
    assert got == ["img1.jpg", "img2.PNG", "img10.png"]
    got = [p.name for p in collect_images([tmp_path], recursive=True)]
    assert got == ["img1.jpg", "img2.PNG", "img10.png", "img3.png"]
    # files as given (any extension, kept for their error), duplicates dropped
    got = collect_images([tmp_path / "readme.md", tmp_path, tmp_path / "img1.jpg"])
    assert [p.name for p in got] == ["readme.md", "img1.jpg", "img2.PNG", "img10.png"]
    assert sorted(["a10", "a9", "A1"], key=natural_key) == ["A1", "a9", "a10"]
    (tmp_path / "nothing").mkdir()
    with pytest.raises(ShapeTreeError, match="holds no image"):
        collect_images([tmp_path / "nothing"])
    with pytest.raises(ShapeTreeError, match="no images given"):
        collect_images([])


def test_batch_records_pictures_errors_and_resume(photos: dict, tmp_path: Path) -> None:
    out = tmp_path / "out"
    images = collect_images([photos["imgs"]])
    assert [p.name for p in images] == [
        "broken.jpg",
        "empty.png",
        "scene1.png",
        "scene2.png",
        "tiny.png",
    ]
    lines: list[str] = []
    s = detect_images(
        photos["model"], images, out_dir=out, k=2, progress=False, report=lines.append
    )
    assert (s.done, s.skipped, s.failed) == (2, 0, 3)
    assert len(lines) == 3 and all(line.startswith("shapetree: ") for line in lines)
    assert "empty (0 bytes)" in " ".join(lines) and "at least 3x3" in " ".join(lines)
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted(
        ["broken.json", "empty.json", "scene1.json", "scene1.png", "scene2.json"]
        + ["scene2.png", "tiny.json", "ranking.json"]  # two good images: a collection
    )
    for name, box in photos["boxes"].items():
        rec = json.loads((out / name.replace(".png", ".json")).read_text())
        assert rec["status"] == "ok" and rec["image_size"] == [190, 150]
        assert 1 <= len(rec["detections"]) <= 2
        best = rec["detections"][0]
        assert box_iou(best["bbox"], box) >= 0.5  # the star is found
        assert len(best["image_points"]) == len(rec["model_points"]) == 30
        assert set(rec["timings"]) == {"edges", "contours", "tables", "stitch", "select"}
    bad = json.loads((out / "broken.json").read_text())
    assert bad["status"] == "error" and "cannot read image" in bad["error"]
    # a second run skips everything (error records count as failed again, and say so)
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    s2 = detect_images(
        photos["model"], images, out_dir=out, k=2, progress=False, report=lines.append
    )
    assert (s2.done, s2.skipped, s2.failed) == (0, 5, 3)
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == before
    assert s2.records[2]["detections"] == s.records[2]["detections"]
    # other parameters do not match the records: recomputed; a missing picture too
    (out / "scene2.png").unlink()
    s3 = detect_images(
        photos["model"], images[2:4], out_dir=out, k=1, progress=False, report=lines.append
    )
    assert (s3.done, s3.skipped) == (2, 0)
    s4 = detect_images(
        photos["model"], images[2:4], out_dir=out, k=1, progress=False, report=lines.append
    )
    assert (s4.done, s4.skipped) == (0, 2)


def test_batch_collection_ranking(photos: dict, tmp_path: Path) -> None:
    """Two photos: every detection of both, ranked by the re-scorer's collection score
    (the default) or by score + appearance_check * agreement, in ``ranking.json``; the
    per-image records do not depend on it."""
    from shapetree.detection import RESCORER_WEIGHTS

    out = tmp_path / "out"
    images = [photos["imgs"] / "scene1.png", photos["imgs"] / "scene2.png"]
    kw = dict(out_dir=out, k=2, pictures=False, progress=False)
    s = detect_images(photos["model"], images, **kw)
    doc = json.loads((out / "ranking.json").read_text())
    assert s.ranking_path == out / "ranking.json" and doc["detections"] == s.ranking
    assert doc["collection_rescore"] is True and "re-scorer" in doc["note"]
    n_dets = sum(len(r["detections"]) for r in s.records)
    assert len(s.ranking) == n_dets and doc["n_images"] == 2
    cs = [d["collection_score"] for d in s.ranking]
    assert cs == sorted(cs, reverse=True)
    for d in s.ranking:
        rec = s.records[[str(i) for i in images].index(d["image"])]
        assert d["score"] == rec["detections"][d["rank"]]["score"]
        assert 0.0 <= d["appearance"] <= 1.0 and d["margin"] <= 0.0 <= d["lead"]
        want = d["base"] + sum(w * d[t] for t, w in RESCORER_WEIGHTS.items())
        assert d["collection_score"] == pytest.approx(want, abs=1e-4)  # terms kept to 1e-6
    colour = DetectParams(collection_rescore=False, appearance_check=0.4)
    s = detect_images(photos["model"], images, params=colour, **kw)
    assert (s.done, s.skipped) == (0, 2)  # the collection fields are not in the key
    for d in s.ranking:
        assert set(d) == {"image", "rank", "bbox", "score", "collection_score", "appearance"}
        assert d["collection_score"] == pytest.approx(d["score"] + 0.4 * d["appearance"], abs=1e-6)
    # a ranking that no longer applies is removed
    kw["params"] = DetectParams(collection_rescore=False)
    off = detect_images(photos["model"], images, **kw)
    assert (off.done, off.skipped) == (0, 2) and off.ranking == []
    assert not (out / "ranking.json").exists()
    # one image has nothing to compare with
    one = detect_images(photos["model"], images[:1], out_dir=tmp_path / "one", progress=False)
    assert one.ranking == [] and not (tmp_path / "one" / "ranking.json").exists()


def test_jsonl_file_resumes_and_stdout(photos: dict, tmp_path: Path, capsys) -> None:
    target = tmp_path / "d.jsonl"
    imgs = [photos["imgs"] / "scene1.png", photos["imgs"] / "broken.jpg"]
    s = detect_images(
        photos["model"],
        imgs,
        out_dir=None,
        jsonl=target,
        progress=False,
        report=lambda m: None,
        k=1,
    )
    recs = [json.loads(line) for line in target.read_text().splitlines()]
    assert [r["status"] for r in recs] == ["ok", "error"] and s.done == 1
    s = detect_images(
        photos["model"],
        imgs,
        out_dir=None,
        jsonl=target,
        progress=False,
        report=lambda m: None,
        k=1,
    )
    assert s.skipped == 2 and len(target.read_text().splitlines()) == 2
    code = main(
        ["detect", str(photos["model"]), str(imgs[0]), "--jsonl", "-", "--no-progress", "-k", "1"]
    )
    out, err = capsys.readouterr()
    assert code == 0
    (rec,) = [json.loads(line) for line in out.splitlines()]
    assert rec["image"] == str(imgs[0]) and len(rec["detections"]) == 1
    assert "1 image(s): 1 searched now" in err and "1 with a detection" in err


def test_cli_batch_exit_status_and_messages(photos: dict, tmp_path: Path, capsys) -> None:
    out = tmp_path / "o"
    args = ["detect", str(photos["model"]), str(photos["imgs"]), "-o", str(out), "-k", "1"]
    code = main([*args, "--no-progress", "--no-pictures"])
    stdout, err = capsys.readouterr()
    assert code == 1  # some images failed; the batch went on
    assert "5 image(s): 2 searched now, 0 already done, 3 failed; 2 with a detection" in stdout
    assert err.count("shapetree: ") == 3 and "Traceback" not in err
    assert not list(out.glob("*.png"))
    code = main([*args, "--no-progress", "--no-pictures"])
    assert code == 1 and "0 searched now, 5 already done, 3 failed" in capsys.readouterr()[0]
    # a model that cannot be read, or a picture name for many images: one line, status 2
    for bad in (
        ["detect", str(tmp_path / "missing.svg"), str(photos["imgs"])],
        ["detect", str(photos["model"]), str(photos["imgs"]), "-o", str(tmp_path / "x.png")],
        ["detect", str(photos["model"]), str(photos["imgs"]), "--edges", "nosuch.tif"],
        ["detect", str(photos["model"]), str(photos["imgs"]), "-p", "edge_method=sobel"],
    ):
        code = main([*bad, "--no-progress"])
        _, err = capsys.readouterr()
        assert code == 2 and err.startswith("shapetree: error: ") and err.count("\n") == 1, err


def test_stored_edge_map_needs_one_image(photos: dict, tmp_path: Path) -> None:
    img = photos["imgs"] / "scene1.png"
    with pytest.raises(ShapeTreeError, match="fits one image"):
        detect_images(photos["model"], [img, img], out_dir=tmp_path, edges=str(img))
    with pytest.raises(ShapeTreeError, match="nowhere to write"):
        detect_images(photos["model"], [img], out_dir=None)
    s = detect_images(
        photos["model"],
        [img],
        out_dir=tmp_path,
        edges="gradient",
        k=1,
        pictures=False,
        progress=False,
        params=DetectParams(min_size=10.0),
    )
    rec = s.records[0]
    assert rec["edges"] == {"method": "gradient"} and rec["params"]["edge_method"] == "gradient"
    assert rec["params"]["min_size"] == 10.0


def test_single_picture_form_uses_the_own_edges(photos: dict, tmp_path: Path, capsys) -> None:
    img = photos["imgs"] / "scene1.png"
    pic, rec = tmp_path / "one.png", tmp_path / "one.json"
    code = main(["detect", str(photos["model"]), str(img), "-o", str(pic), "--json", str(rec)])
    text = capsys.readouterr().out
    assert code == 0 and "detection(s) of" in text and pic.is_file()
    doc = json.loads(rec.read_text())
    assert doc["edges"] == "own" and doc["params"]["edge_method"] == "own"
    assert box_iou(doc["detections"][0]["bbox"], photos["boxes"]["scene1.png"]) >= 0.5


def test_cli_batch_says_when_an_image_has_no_detection(
    photos: dict, tmp_path: Path, capsys
) -> None:
    blank = tmp_path / "white.png"
    Image.new("L", (80, 60), 255).save(blank)  # no edge at all: nothing to find
    args = ["detect", str(photos["model"]), str(blank), "-o", str(tmp_path / "o")]
    code = main([*args, "--no-progress", "--no-pictures", "-k", "1"])
    out = capsys.readouterr()[0]
    assert code == 0 and "white.png: no detection" in out
    assert "1 image(s): 1 searched now, 0 already done, 0 failed; 0 with a detection" in out


def test_cli_collection_ranking(photos: dict, tmp_path: Path, capsys) -> None:
    out = tmp_path / "o"
    imgs = [str(photos["imgs"] / "scene1.png"), str(photos["imgs"] / "scene2.png")]
    args = ["detect", str(photos["model"]), *imgs, "-o", str(out), "-k", "1", "--no-pictures"]
    code = main([*args, "--no-progress"])
    stdout, _ = capsys.readouterr()
    assert code == 0 and "collection ranking of 2 detection(s) in 2 images" in stdout
    assert "(collection score: re-scorer)" in stdout
    assert f"ranking: {out / 'ranking.json'}" in stdout
    doc = json.loads((out / "ranking.json").read_text())
    assert doc["collection_rescore"] is True and len(doc["detections"]) == 2
    colour = ["-p", "collection_rescore=False", "-p", "appearance_check=0.4"]
    code = main([*args, "--no-progress", *colour])
    stdout, _ = capsys.readouterr()
    assert code == 0 and "score + W * colour agreement" in stdout
    doc = json.loads((out / "ranking.json").read_text())
    assert doc["appearance_check"] == 0.4 and doc["collection_rescore"] is False
    code = main([*args, "--no-progress", "-p", "appearance_check=-1"])
    _, err = capsys.readouterr()
    assert code == 2 and "appearance_check must be a finite number >= 0" in err
    code = main([*args, "--no-progress", "-p", "appearance_check=0.4"])
    _, err = capsys.readouterr()
    assert code == 2 and "has its own colour weight" in err
