"""The upright prior of the stitching (``DetectParams.upright_cost``, ``_upright``)."""

from __future__ import annotations

import numpy as np
import pytest

from shapetree import ShapeTreeError
from shapetree.detection import DetectParams, detect, make_model
from shapetree.detection._upright import piece_turn_cos


def _shape(t: np.ndarray) -> np.ndarray:
    r = 1 + 0.3 * np.cos(3 * t) + 0.15 * np.sin(2 * t)  # no symmetry
    return np.c_[r * np.cos(t), r * np.sin(t)]


def _turn(p: np.ndarray, ang: float, scale: float, shift: tuple[float, float]) -> np.ndarray:
    rot = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
    return (p - p.mean(axis=0)) @ rot.T * scale + np.asarray(shift)


@pytest.mark.parametrize("deg", [0.0, 25.0, 90.0, 140.0, 180.0])
def test_turn_of_a_model_interval_is_its_rotation(deg: float) -> None:
    model = _shape(np.linspace(0, 2 * np.pi, 30, endpoint=False)) * 50 + 100
    a, n = 4, 9  # the interval of samples 4 .. 13
    piece = _turn(model[a : a + n + 1], np.deg2rad(deg), 1.6, (300.0, 80.0))
    cos = piece_turn_cos(model, [piece])
    assert cos.shape == (2, 30, 30)
    assert cos[0, a, n] == pytest.approx(np.cos(np.deg2rad(deg)), abs=1e-9)
    # read backwards, the piece runs against the interval: half a turn more
    assert cos[1, a, n] == pytest.approx(-np.cos(np.deg2rad(deg)), abs=0.05)
    assert np.all(np.abs(cos) <= 1 + 1e-12)


def test_turn_of_a_point_piece_is_a_clear_error() -> None:
    from shapetree import CurveError

    model = _shape(np.linspace(0, 2 * np.pi, 12, endpoint=False)) * 40
    with pytest.raises(CurveError, match="zero length"):
        piece_turn_cos(model, [np.array([[5.0, 5.0], [5.0, 5.0]])])


def _pieces(ang: float, shift: tuple[float, float], cut: tuple[float, float] | None):
    """The model outline placed turned by ``ang``, in three open pieces, the arc
    ``cut`` (radians of the shape's parameter) left out."""
    centre = _shape(np.linspace(0, 2 * np.pi, 400, endpoint=False)).mean(axis=0)
    rot = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
    runs = []
    for a, b in ((0.3, 2.5), (2.5, 5.2), (5.2, 0.3 + 2 * np.pi)):
        t = np.linspace(a, b, 300)
        if cut is not None:
            t = t[(t < cut[0]) | (t > cut[1])]
        for s in np.split(t, np.flatnonzero(np.diff(t) > 0.05) + 1):  # at the cut
            if len(s) > 20:
                runs.append((_shape(s) - centre) @ rot.T * 60 + np.asarray(shift))
    return runs


def test_upright_cost_prefers_the_placement_standing_as_drawn() -> None:
    model = make_model(_shape(np.linspace(0, 2 * np.pi, 400, endpoint=False)) * 60, m=24)
    upright = _pieces(0.0, (120.0, 150.0), cut=(1.0, 1.5))  # a gap: dearer to match
    turned = _pieces(np.pi / 2, (340.0, 150.0), cut=None)  # whole, but on its side
    conts = upright + turned
    kw = dict(k=2, outline_check=0.0, context_check=0.0, frame_prior=0.0)
    plain = detect(model, None, contours=conts, upright_cost=0.0, **kw)
    assert plain[0].bbox[0] > 230  # rotation invariant: the whole turned copy wins
    prior = detect(model, None, contours=conts, upright_cost=0.5, **kw)
    assert prior[0].bbox[2] < 230  # the upright copy ranks first
    # ... and the turned copy's best match costs more, but at most upright_cost (its
    # old match, each piece turned by a quarter, is still there at that price)
    rise = next(d.cost for d in prior if d.bbox[0] > 230) - plain[0].cost
    assert 0.05 < rise <= 0.5 + 1e-9
    # the upright copy's cost barely moves
    assert abs(prior[0].cost - next(d.cost for d in plain if d.bbox[2] < 230)) < 0.05


@pytest.mark.parametrize("bad", [-0.1, float("nan"), float("inf"), True, "0.25"])
def test_upright_cost_must_be_finite_and_not_negative(bad: object) -> None:
    with pytest.raises(ShapeTreeError, match="upright_cost must be a finite number >= 0"):
        DetectParams(upright_cost=bad)  # checked when the parameters are made
    model = make_model(_shape(np.linspace(0, 2 * np.pi, 100, endpoint=False)) * 60, m=16)
    with pytest.raises(ShapeTreeError, match="upright_cost"):
        detect(model, None, contours=[np.c_[np.arange(50.0), np.zeros(50)]], upright_cost=bad)


def test_cli_refuses_a_bad_upright_cost_before_any_output(tmp_path, capsys) -> None:
    from shapetree.cli import main

    model = tmp_path / "model.npy"
    np.save(model, _shape(np.linspace(0, 2 * np.pi, 100, endpoint=False)) * 60)
    out = tmp_path / "out"  # the parameters are refused before any image is read
    code = main(["detect", str(model), str(model), "--param", "upright_cost=-1", "-o", str(out)])
    assert code == 2
    assert "upright_cost must be a finite number >= 0" in capsys.readouterr().err
    assert not out.exists()


def test_upright_cost_default() -> None:
    assert DetectParams().upright_cost == 0.25  # chosen on ETHZ (ethz_detector_params.py)
