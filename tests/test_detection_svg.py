"""Detection models drawn as SVG (detection._svg) against geometry computed by hand."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from shapetree import ShapeTreeError
from shapetree.detection import load_model
from shapetree.detection._svg import parse_path_d, read_svg_outline

SVG = '<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 200 200">{}</svg>'


def _write(tmp_path: Path, body: str, name: str = "m.svg") -> Path:
    p = tmp_path / name
    p.write_text(SVG.format(body), encoding="utf-8")
    return p


def test_lines_absolute_relative_and_implicit_repeats_agree() -> None:
    square = np.array([[10, 10], [60, 10], [60, 40], [10, 40]], float)
    for d in (
        "M10 10 L60 10 L60 40 L10 40 Z",
        "M10,10 60,10 60,40 10,40z",  # implicit line-tos after a move
        "m10 10 l50 0 l0 30 l-50 0 z",
        "M10 10 H60 V40 H10 Z",
        "M 10 10 h 50 v 30 h -50 Z",
        "M10 10h50v30h-50z",
    ):
        ((pts, closed),) = parse_path_d(d)
        assert closed, d
        assert np.allclose(pts, square), d


def test_cubic_and_quadratic_beziers_are_sampled_on_the_curve() -> None:
    p0, p1, p2, p3 = map(np.array, ([0.0, 0.0], [0.0, 30.0], [40.0, 30.0], [40.0, 0.0]))
    ((pts, closed),) = parse_path_d("M0 0 C0 30 40 30 40 0", bezier_samples=10)
    assert not closed and len(pts) == 11
    t = np.linspace(0, 1, 11)[:, None]
    ref = (1 - t) ** 3 * p0 + 3 * (1 - t) ** 2 * t * p1 + 3 * (1 - t) * t**2 * p2 + t**3 * p3
    assert np.allclose(pts, ref)
    # S reflects the previous control point: "C 0 30 40 30 40 0 S 80 -30 80 0" is the
    # same as writing the reflected control point (40, -30) out in a second C
    a = parse_path_d("M0 0 C0 30 40 30 40 0 S80 -30 80 0")[0][0]
    b = parse_path_d("M0 0 C0 30 40 30 40 0 C40 -30 80 -30 80 0")[0][0]
    assert np.allclose(a, b)
    # relative c equals absolute C
    c = parse_path_d("M10 10 c0 30 40 30 40 0")[0][0]
    assert np.allclose(c, parse_path_d("M10 10 C10 40 50 40 50 10")[0][0])
    # quadratic: the midpoint of Q p0 p1 p2 is (p0 + 2 p1 + p2) / 4; T reflects p1
    ((q, _),) = parse_path_d("M0 0 Q20 40 40 0", bezier_samples=2)
    assert np.allclose(q[1], [20.0, 20.0])
    t1 = parse_path_d("M0 0 Q20 40 40 0 T80 0")[0][0]
    t2 = parse_path_d("M0 0 Q20 40 40 0 Q60 -40 80 0")[0][0]
    assert np.allclose(t1, t2)


def test_subpaths_and_the_longest_is_the_outline(tmp_path: Path) -> None:
    subs = parse_path_d("M0 0 L10 0 L10 10 Z m 2 2 l 1 0 l 0 1 z")
    assert len(subs) == 2
    assert np.allclose(subs[1][0][0], [2.0, 2.0])  # relative to the closed sub-path's start
    p = _write(tmp_path, '<path d="M5 5 h2 v2 h-2 z M0 0 H100 V50 H0 Z"/>')
    pts, closed = read_svg_outline(p)
    assert closed and np.ptp(pts, axis=0).tolist() == [100.0, 50.0]


def test_polygon_polyline_and_transforms(tmp_path: Path) -> None:
    pts, closed = read_svg_outline(_write(tmp_path, '<polygon points="0,0 30,0 30,20 0,20"/>'))
    assert closed and pts.shape == (4, 2)
    pts, closed = read_svg_outline(_write(tmp_path, '<polyline points="0 0 30 0 30 20"/>'))
    assert not closed and pts.shape == (3, 2)
    body = (
        '<g transform="translate(100, 50)"><path transform="scale(2)" '
        'd="M0 0 L10 0 L10 5 L0 5 Z"/></g>'
    )
    pts, _ = read_svg_outline(_write(tmp_path, body))
    assert np.allclose(pts, [[100, 50], [120, 50], [120, 60], [100, 60]])
    pts, _ = read_svg_outline(
        _write(tmp_path, '<path transform="rotate(90)" d="M0 0 L10 0 L10 5 Z"/>')
    )
    assert np.allclose(pts, [[0, 0], [0, 10], [-5, 10]], atol=1e-9)
    pts, _ = read_svg_outline(
        _write(tmp_path, '<path transform="matrix(1 0 0 1 3 4)" d="M0 0 L10 0 L10 5 Z"/>')
    )
    assert np.allclose(pts[0], [3, 4])


@pytest.mark.parametrize(
    "body, match",
    [
        ('<path d="M0 0 A 10 10 0 0 1 20 0 Z"/>', "arcs"),
        ("<circle cx='5' cy='5' r='4'/>", "no <path>"),
        ('<path d="L 10 10"/>', "must start with a move"),
        ('<path d="M0 0 L 10"/>', "needs 2 numbers"),
        ('<path d="M0 0 L 10 10 # 5"/>', "unexpected"),
        ('<path transform="perspective(3)" d="M0 0 L10 0 L10 5 Z"/>', "not understood"),
        ('<path d="M0 0 L0 0"/>', "draws no line|fewer than 3"),
    ],
)
def test_unsupported_content_is_refused_clearly(tmp_path: Path, body: str, match: str) -> None:
    with pytest.raises(ShapeTreeError, match=match):
        read_svg_outline(_write(tmp_path, body))


def test_unreadable_files(tmp_path: Path) -> None:
    with pytest.raises(ShapeTreeError, match="not found"):
        read_svg_outline(tmp_path / "missing.svg")
    (tmp_path / "bad.svg").write_text("<svg><path d='M0 0'", encoding="utf-8")
    with pytest.raises(ShapeTreeError, match="cannot read SVG"):
        read_svg_outline(tmp_path / "bad.svg")


def test_load_model_reads_svg_like_the_same_points(tmp_path: Path) -> None:
    t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    ring = np.c_[50 + 40 * np.cos(t), 50 + 25 * np.sin(t)]
    d = "M " + " L ".join(f"{x:.6f} {y:.6f}" for x, y in ring) + " Z"
    svg = _write(tmp_path, f'<path d="{d}"/>')
    np.savetxt(tmp_path / "ring.csv", ring, delimiter=",")
    a = load_model(svg, m=24)
    b = load_model(tmp_path / "ring.csv", m=24)
    assert a.name == "m" and a.points.shape == (24, 2)
    assert np.allclose(a.points, b.points, atol=1e-6)
