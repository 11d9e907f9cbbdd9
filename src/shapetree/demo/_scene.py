"""A cluttered scene drawn by the project itself, for the demo's detection step (paper §4).

:func:`detection_scene` draws a randomly deformed demo shape as a dark outline broken into
pieces with gaps, among distractor curves (smooth random strokes, arcs, straight lines) on
a textured background (fine random blotches); it returns the picture, the undeformed
model and the object's true box.  :func:`box_iou` scores a detection against that box.
Everything is seeded; nothing is downloaded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from shapetree._errors import ShapeTreeError

__all__ = ["DetectionScene", "detection_scene", "box_iou"]


@dataclass
class DetectionScene:
    """A synthetic detection problem with a known answer.

    Attributes
    ----------
    image : ndarray, shape (H, W, 3), float64
        RGB in ``[0, 1]``.
    model : ndarray, shape (n, 2)
        The undeformed shape (unit size, closed), to be searched for.
    outline : ndarray, shape (n, 2)
        The deformed outline as placed in the image (px, before the gaps were cut).
    box : tuple of float
        ``(x1, y1, x2, y2)``: the outline's bounding box (px).
    name : str
        The demo shape.
    """

    image: NDArray[np.float64]
    model: NDArray[np.float64]
    outline: NDArray[np.float64]
    box: tuple[float, float, float, float]
    name: str


def box_iou(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    """Intersection over union of two boxes ``(x1, y1, x2, y2)``."""
    ix = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = ix * iy
    area = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return float(inter / area) if area > 0 else 0.0


def _stamp(canvas: NDArray, pts: NDArray, value: float, width: float) -> None:
    """Draw the polyline ``pts`` (px, open) into ``canvas`` with a round pen."""
    h, w = canvas.shape
    seg = np.diff(pts, axis=0)
    n = np.maximum(1, np.ceil(np.hypot(*seg.T) * 2).astype(int))
    dense = np.vstack(
        [
            p0 + np.linspace(0, 1, k, endpoint=False)[:, None] * d
            for p0, d, k in zip(pts[:-1], seg, n)
        ]
        + [pts[-1:]]
    )
    r = int(np.ceil(width / 2))
    offs = [
        (dy, dx)
        for dy in range(-r, r + 1)
        for dx in range(-r, r + 1)
        if dx * dx + dy * dy <= (width / 2) ** 2 + 0.25
    ]
    cols = np.rint(dense[:, 0]).astype(int)
    rows = np.rint(dense[:, 1]).astype(int)
    for dy, dx in offs:
        rr, cc = rows + dy, cols + dx
        ok = (rr >= 0) & (rr < h) & (cc >= 0) & (cc < w)
        canvas[rr[ok], cc[ok]] = value


def _random_stroke(rng: np.random.Generator, h: int, w: int, length: float) -> NDArray:
    """A smooth random open curve of about ``length`` px."""
    n = 40
    turn = ndimage.gaussian_filter1d(rng.normal(0, 0.35, n), 3.0)
    ang = rng.uniform(0, 2 * np.pi) + np.cumsum(turn)
    step = length / n
    start = rng.uniform([0.1 * w, 0.1 * h], [0.9 * w, 0.9 * h])
    return start + np.cumsum(np.c_[np.cos(ang), np.sin(ang)] * step, axis=0)


def detection_scene(
    name: str = "hand",
    *,
    size: tuple[int, int] = (240, 320),
    object_size: float = 110.0,
    n_gaps: int = 3,
    gap: float = 0.05,
    n_distractors: int = 9,
    deform_scale: float = 0.03,
    seed: int = 0,
) -> DetectionScene:
    """Draw a cluttered scene holding one deformed, broken outline of a demo shape.

    Parameters
    ----------
    name : str
        A demo shape (:func:`shapetree.demo.demo_shape_names`).
    size : (int, int)
        Image height and width (px).
    object_size : float
        Longer side of the object's box (px).
    n_gaps : int
        Gaps cut into the outline ...
    gap : float
        ... each this share of its length.
    n_distractors : int
        Distractor curves (random strokes, arcs and lines, in turn).
    deform_scale : float
        Shape-tree deformation noise (:func:`shapetree.tree.deform`).
    seed : int

    Returns
    -------
    DetectionScene

    Raises
    ------
    ShapeTreeError
        For an unknown shape or a scene too small for the object.
    """
    from shapetree.demo._shapes import demo_shape
    from shapetree.tree import build_shape_tree, deform

    h, w = size
    if min(h, w) < object_size + 20:
        raise ShapeTreeError(f"scene {size} is too small for an object of {object_size} px")
    rng = np.random.default_rng(seed)
    model = demo_shape(name, n_points=128)
    shape = deform(build_shape_tree(model, closed=True), deform_scale, rng=rng)
    ang = rng.uniform(-0.25, 0.25)
    rot = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
    shape = (shape - shape.mean(axis=0)) @ rot.T
    shape *= object_size / np.ptp(shape, axis=0).max()
    lo, hi = shape.min(axis=0), shape.max(axis=0)
    centre = rng.uniform([12 - lo[0], 12 - lo[1]], [w - 12 - hi[0], h - 12 - hi[1]])
    outline = shape + centre
    box = tuple(float(v) for v in (*outline.min(axis=0), *outline.max(axis=0)))

    # background: mid grey, fine low-contrast blotches (texture without boundaries)
    grey = 0.62 + 0.10 * ndimage.gaussian_filter(rng.standard_normal((h, w)), 1.2)
    ink = np.full((h, w), np.nan)
    for i in range(n_distractors):
        kind = i % 3
        if kind == 0:
            pts = _random_stroke(rng, h, w, rng.uniform(60, 160))
        elif kind == 1:
            c = rng.uniform([0, 0], [w, h])
            r = rng.uniform(20, 60)
            t = rng.uniform(0, 2 * np.pi) + np.linspace(0, rng.uniform(1.5, 3.5), 40)
            pts = c + r * np.c_[np.cos(t), np.sin(t)]
        else:
            a = rng.uniform([0, 0], [w, h])
            d = rng.normal(size=2)
            pts = a + np.linspace(0, rng.uniform(60, 140), 2)[:, None] * d / np.linalg.norm(d)
        _stamp(ink, pts, rng.uniform(0.15, 0.3), 2.0)
    # the object: closed outline with gaps cut out
    n = len(outline)
    keep = np.ones(n + 1, bool)
    starts = rng.choice(n, size=n_gaps, replace=False)
    for s in starts:
        keep[(s + np.arange(max(1, int(round(gap * n))))) % n] = False
    ring = np.vstack([outline, outline[:1]])
    keep[-1] = keep[0]
    i = 0
    while i < n + 1:
        if keep[i]:
            j = i
            while j + 1 < n + 1 and keep[j + 1]:
                j += 1
            if j > i:
                _stamp(ink, ring[i : j + 1], 0.12, 2.5)
            i = j + 1
        else:
            i += 1
    img = np.where(np.isnan(ink), grey, ink)
    img = ndimage.gaussian_filter(img, 0.7)
    tint = np.array([1.0, 0.97, 0.9])
    rgb = np.clip(img[:, :, None] * tint[None, None, :], 0.0, 1.0)
    return DetectionScene(rgb, model, outline, box, name)
