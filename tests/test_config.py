"""The single matcher configuration: validation, presets, and one cost for every entry point."""

from __future__ import annotations

import argparse
import dataclasses
import json

import numpy as np
import pytest

from shapetree import ShapeTreeError
from shapetree.cli import build_parser, main
from shapetree.matching import OPTIONS, PRESETS, MatchConfig, match, mirror_curve
from shapetree.retrieval import directed_costs, distance_matrix


def _blob(seed: int, n: int = 90) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 1 + sum(rng.uniform(-0.15, 0.15) * np.cos(k * t + rng.uniform(0, 6)) for k in (2, 3, 5))
    return np.c_[r * np.cos(t), 0.8 * r * np.sin(t)]


# ------------------------------------------------------------------ validation


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("n_points", 3),
        ("n_points", 10.5),
        ("weight", 0),
        ("weight", float("nan")),
        ("length_power", -1),
        ("occlusion", 0.0),
        ("n_trees", 0),
        ("split", "middle"),
        ("mirror", "yes"),
        ("band", 0.5),
        ("phases", 0),
        ("target_factor", 1.5),
        ("segment_weight", -0.1),
        ("smooth", 0.7),
        ("symmetrize", "sum"),
        ("precision", "float16"),
        ("dif", "poincare"),
        ("matcher", "both"),
        ("replace_any", "yes"),
    ],
)
def test_bad_values_name_the_option(field: str, value: object) -> None:
    with pytest.raises(ShapeTreeError, match=field):
        MatchConfig(**{field: value})


def test_config_is_immutable_and_round_trips() -> None:
    cfg = MatchConfig.preset("paper", occlusion=0.5)
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.n_points = 10  # type: ignore[misc]
    assert MatchConfig.from_dict(json.loads(json.dumps(cfg.as_dict()))) == cfg
    assert hash(cfg) == hash(MatchConfig.from_dict(cfg.as_dict()))
    with pytest.raises(ShapeTreeError, match="unknown matching option"):
        cfg.replace(n_point=4)
    with pytest.raises(ShapeTreeError, match="unknown preset"):
        MatchConfig.preset("best")
    with pytest.raises(ShapeTreeError, match="need n_points"):
        MatchConfig(n_points=None, phases=2)


def test_every_option_is_described_once() -> None:
    assert list(OPTIONS) == [f.name for f in dataclasses.fields(MatchConfig)]
    for spec in OPTIONS.values():
        assert spec["type"] in (int, float, str, bool) and spec["help"]


def test_presets() -> None:
    assert set(PRESETS) == {"paper", "general", "kimia99", "mpeg7", "swedish_leaf", "fused"}
    p = PRESETS["paper"]  # one sampling, no mirror, no band, no phases, lambda ~ length
    assert (p.mirror, p.band, p.phases, p.target_factor, p.length_power) == (
        False,
        None,
        1,
        1,
        1.0,
    )
    assert p.segment_weight == 1.0 and p.symmetrize == "none" and p.occlusion is None
    assert PRESETS["general"] == MatchConfig()  # the dataclass defaults are the general preset
    for name, cfg in PRESETS.items():  # the issue-15 options are off in every preset
        assert (cfg.dif, cfg.matcher, cfg.replace_any) == ("procrustes", "directed", False)
        # and the height-function fusion in ``fused`` alone
        assert (cfg.height_weight > 0) == (name == "fused")
    assert match(_blob(1), _blob(2)).cost == match(_blob(1), _blob(2), "general").cost


# ------------------------------------------------------------------ one cost everywhere

CONFIGS = {
    "general": PRESETS["general"].replace(n_points=24),
    "paper": PRESETS["paper"].replace(n_points=20),
    "occlusion+min": MatchConfig(
        n_points=20, n_trees=2, occlusion=1.0, symmetrize="min", phases=2, band=None
    ),
    "swedish": PRESETS["swedish_leaf"].replace(n_points=16, smooth=0.01),
}


@pytest.mark.parametrize("name", sorted(CONFIGS))
def test_same_pair_same_cost_everywhere(name: str, tmp_path, capsys) -> None:
    """``shapetree match``, ``shapetree search``, ``match()`` and ``distance_matrix()``
    agree to 1e-6 relative for the same configuration (float64 tables)."""
    cfg = CONFIGS[name].replace(precision="float64")
    a, b, c = _blob(3), 1.7 * _blob(4)[::-1][::-1] + 2, _blob(5)
    files = []
    for i, pts in enumerate((a, b, c)):
        f = tmp_path / f"s{i}.csv"
        np.savetxt(f, pts, delimiter=",")
        files.append(str(f))
    flags = []
    for key, value in cfg.as_dict().items():
        flag = "--" + key.replace("_", "-")
        if isinstance(value, bool):
            flags.append(flag if value else "--no-" + key.replace("_", "-"))
        else:
            flags += [flag, "none" if value is None else str(value)]
    api = match(a, b, cfg).cost
    D = distance_matrix([a], [b, c], cfg, progress=False, workers=1)
    assert D[0, 0] == pytest.approx(api, rel=1e-6, abs=1e-12)
    assert match(a, c, cfg).cost == pytest.approx(D[0, 1], rel=1e-6, abs=1e-12)

    assert main(["match", files[0], files[1], "--json", str(tmp_path / "m.json"), *flags]) == 0
    capsys.readouterr()
    cli = json.loads((tmp_path / "m.json").read_text())
    assert MatchConfig.from_dict(cli["config"]) == cfg
    assert cli["cost"] == pytest.approx(api, rel=1e-6, abs=1e-12)

    out = tmp_path / "r.json"
    code = main(
        ["search", files[0], files[1], files[2], "--json", str(out), "--no-progress"] + flags
    )
    assert code == 0
    capsys.readouterr()
    ranking = {r["shape"]: r["distance"] for r in json.loads(out.read_text())["ranking"]}
    assert ranking[files[1]] == pytest.approx(api, rel=1e-6, abs=1e-12)
    assert ranking[files[2]] == pytest.approx(D[0, 1], rel=1e-6, abs=1e-12)


def test_distances_command_uses_the_same_configuration(tmp_path, capsys) -> None:
    cfg = CONFIGS["paper"].replace(precision="float64", symmetrize="mean")
    shapes = [_blob(s) for s in (6, 7, 8)]
    files = []
    for i, pts in enumerate(shapes):
        f = tmp_path / f"s{i}.csv"
        np.savetxt(f, pts, delimiter=",")
        files.append(str(f))
    out = tmp_path / "D.npz"
    argv = ["distances", *files, "-o", str(out), "--no-cache", "--no-progress", "--preset", "paper"]
    argv += ["--n-points", "20", "--precision", "float64", "--symmetrize", "mean"]
    assert main(argv) == 0
    capsys.readouterr()
    z = np.load(out)
    want = distance_matrix(shapes, None, cfg, progress=False, workers=1)
    np.testing.assert_allclose(z["D"], np.maximum(want, 0), rtol=1e-12)
    assert json.loads(str(z["config"]))["config"] == cfg.as_dict()
    for i in range(3):
        for j in range(3):
            assert match(shapes[i], shapes[j], cfg).cost == pytest.approx(
                want[i, j], rel=1e-6, abs=1e-12
            )


def _matching_flags(command: str) -> dict[str, tuple]:
    parser = build_parser([command])
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    p = sub.choices[command]
    return {
        a.dest: (tuple(a.option_strings), a.type, a.choices)
        for a in p._actions
        if a.dest in OPTIONS or a.dest == "preset"
    }


def test_matching_commands_expose_the_same_flags() -> None:
    ref = _matching_flags("match")
    assert set(ref) == set(OPTIONS) | {"preset"}
    for command in ("search", "distances", "evaluate", "demo"):
        got = _matching_flags(command)
        assert {k: v[0] for k, v in got.items()} == {k: v[0] for k, v in ref.items()}, command


def test_preset_flag_and_changes_reach_the_matcher(tmp_path, capsys) -> None:
    a, b = _blob(9), _blob(10)
    fa, fb = tmp_path / "a.csv", tmp_path / "b.csv"
    np.savetxt(fa, a, delimiter=",")
    np.savetxt(fb, b, delimiter=",")
    for argv, cfg in [
        ([], PRESETS["general"]),
        (["--preset", "paper"], PRESETS["paper"]),
        (["--preset", "mpeg7", "--n-points", "24"], PRESETS["mpeg7"].replace(n_points=24)),
        (["--occlusion", "none", "--band", "0"], PRESETS["general"].replace(band=None)),
    ]:
        assert main(["match", str(fa), str(fb), "--json", str(tmp_path / "m.json"), *argv]) == 0
        capsys.readouterr()
        doc = json.loads((tmp_path / "m.json").read_text())
        assert MatchConfig.from_dict(doc["config"]) == cfg
        assert doc["cost"] == pytest.approx(match(a, b, cfg).cost, rel=1e-6)


def test_issue15_options_reach_match_from_the_command_line(tmp_path, capsys) -> None:
    a, b = _blob(11, 40), _blob(12, 40)
    fa, fb = tmp_path / "a.csv", tmp_path / "b.csv"
    np.savetxt(fa, a, delimiter=",")
    np.savetxt(fb, b, delimiter=",")
    base = PRESETS["general"].replace(n_points=12, phases=1)
    for argv, cfg in [
        (["--dif", "hyperbolic"], base.replace(dif="hyperbolic")),
        (["--matcher", "symmetric"], base.replace(matcher="symmetric")),
        (["--replace-any", "--occlusion", "1"], base.replace(replace_any=True, occlusion=1.0)),
    ]:
        out = tmp_path / "m.json"
        flags = ["--n-points", "12", "--phases", "1", *argv]
        assert main(["match", str(fa), str(fb), "--json", str(out), *flags]) == 0
        capsys.readouterr()
        doc = json.loads(out.read_text())
        assert MatchConfig.from_dict(doc["config"]) == cfg
        assert doc["cost"] == pytest.approx(match(a, b, cfg).cost, rel=1e-6)


# ------------------------------------------------------------------ mirror and phases


def test_mirror_invariance_and_correspondence_in_original_indices() -> None:
    a = _blob(11, n=40)
    b = mirror_curve(a) * 2.0 + 5.0  # b[j] = mirror(a[n - 1 - j]), scaled and moved
    raw = MatchConfig(n_points=None, n_trees=1, band=None, phases=1, precision="float64")
    assert match(a, b, raw.replace(mirror=False)).cost > 1e-3
    res = match(a, b, raw)
    assert res.cost < 1e-9 and res.mirrored
    n = a.shape[0]
    # each point of a lands on its own mirror image in b
    np.testing.assert_allclose(np.mod(res.a_to_b, n), (n - 1 - np.arange(n)) % n, atol=1e-9)
    np.testing.assert_allclose(res.pairs()[:, 2:], b[(n - 1 - np.arange(n)) % n], atol=1e-9)


def test_phases_never_raise_the_cost_and_reach_the_engine() -> None:
    a, b = _blob(12), _blob(13)
    one = MatchConfig(n_points=24, phases=1, precision="float64")
    four = one.replace(phases=4)
    assert match(a, b, four).cost <= match(a, b, one).cost + 1e-12
    c = directed_costs([a], [b], four, progress=False, workers=1)
    assert c.min() == pytest.approx(match(a, b, four).cost, rel=1e-6)


def test_symmetrize_min_is_symmetric() -> None:
    a, b = _blob(14), _blob(15)
    cfg = MatchConfig(n_points=24, symmetrize="min", precision="float64")
    r = match(a, b, cfg)
    assert r.cost == pytest.approx(match(b, a, cfg).cost, rel=1e-9)
    assert r.cost == pytest.approx(min(r.forward_cost, r.backward_cost))


# ------------------------------------------------------------------ the general preset on data


def test_general_preset_costs_little_against_a_rotated_image() -> None:
    """For the first shape of a handful of MPEG-7 classes, the ``general`` cost against its
    own image rotated by 37 degrees (re-traced) is, in the median, at most 0.1 x its cost
    against the nearest of shapes 2-4 of its class (``paper``: well above)."""
    from PIL import Image

    from shapetree import datasets
    from shapetree.curves import curve_from_image

    classes = ["apple", "bat", "bell", "camel", "device0", "fork"]
    ds = datasets.load("mpeg7", n_points=None, per_class=4, classes=classes, progress=False)
    labels = np.asarray(ds.labels)
    ratios: dict[str, list[float]] = {"general": [], "paper": []}
    for c in classes:
        idx = np.flatnonzero(labels == c)
        img = Image.open(ds.paths[idx[0]]).convert("L")
        grey = np.asarray(img)
        bg = int(np.median(np.r_[grey[0], grey[-1], grey[:, 0], grey[:, -1]]))
        rotated = curve_from_image(
            np.asarray(img.rotate(37, resample=Image.NEAREST, expand=True, fillcolor=bg))
        )
        own = ds.curves[idx[0]]
        for name in ratios:
            near = min(match(own, ds.curves[i], name).cost for i in idx[1:4])
            ratios[name].append(match(own, rotated, name).cost / near)
    assert np.median(ratios["general"]) <= 0.1, ratios
    assert np.median(ratios["paper"]) > np.median(ratios["general"])


def test_search_ranks_by_the_match_cost() -> None:
    from shapetree.retrieval import search

    q = _blob(20)
    db = [_blob(21), 2.0 * q + 1.0, _blob(22), mirror_curve(q)]
    cfg = MatchConfig(n_points=20, precision="float64")
    idx, dist = search(q, db, cfg, workers=1)
    assert set(idx[:2].tolist()) == {1, 3}  # the scaled copy and the mirror image come first
    assert np.all(np.diff(dist) >= 0)
    for i, d in zip(idx, dist):
        assert d == pytest.approx(max(match(q, db[i], cfg).cost, 0.0), rel=1e-6, abs=1e-12)
    top, _ = search(q, db, cfg, k=2, workers=1)
    assert top.tolist() == idx[:2].tolist()
    with pytest.raises(ShapeTreeError, match="non-empty"):
        search(q, [], cfg)
