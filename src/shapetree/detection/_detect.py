"""Detecting a deformable model in a cluttered image (paper §4, all four stages)."""

from __future__ import annotations

import dataclasses
import numbers
import os
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from shapetree._errors import ImageError, ShapeTreeError
from shapetree.curves import resample
from shapetree.curves._validate import ACCEPTED_FORMS, _as_xy
from shapetree.geometry import outline_dif

from ._contours import TracedContour, polyline_length, trace_contours_detailed
from ._edges import EDGE_METHODS, WEIGHTED_METHODS, edge_map, load_edges, load_image
from ._model import DetectionModel, load_model
from ._stitch import complete_matches, run_stitch
from ._tables import contour_tables
from ._template import TEMPLATE_TERMS, grown_fit, template_fields, template_model, template_terms
from ._upright import piece_turn_cos
from ._verify import context_agreement

#: the :class:`DetectParams` fields of the collection stage (several images, one model):
#: they re-rank detections across images and never change one image's detections
COLLECTION_FIELDS = ("collection_rescore", "appearance_check", "appearance_reference")

__all__ = ["Detection", "DetectParams", "detect", "detect_detailed", "DetectionRun"]


#: :class:`DetectParams` weights and lengths that must be finite numbers >= 0
_NON_NEGATIVE = ("frame_prior", "border_margin", "outline_check", "context_check", "upright_cost")


@dataclass(frozen=True)
class DetectParams:
    """Parameters of :func:`detect` (all lengths in image pixels).

    Attributes
    ----------
    m : int
        Model samples for the contour tables and the stitching (30).
    threshold, low, min_length, max_turn, turn_window, smooth
        Contour tracing, see :func:`trace_contours` (0.15, None, 15 px,
        60 degrees, 5 px, 1 px).
    max_contours : int
        Keep the contours with the largest ``length * mean strength`` (120).
    contour_spacing : float
        Contours are resampled for the tables with about this spacing (6 px) ...
    contour_min_points, contour_max_points : int
        ... but with at least 3 and at most 24 points (``contour_min_points >= 2``: an
        open polyline needs its two ends; ``contour_max_points >= contour_min_points``).
    tau : float
        Max endpoint distance for a direct composition (12 px).
    lam : float
        Weight of the composition triangle terms (1.0).
    gap_cost : float
        Cost of leaving the whole model unmatched (gaps cost this times their
        share of the model's length) (0.8).
    piece_cost : float
        Fixed cost per contour used (0.01).
    table_weight : float
        Multiplier of the contour-vs-model table costs (3.0).
    beam, per_end : int
        Matches kept per model interval (32), at most ``per_end`` (3) of them
        with the same image start (or end) endpoint.
    max_gap : int or None
        Longest gap inside an interval, in model segments (default ``m // 2``).
    gap_beam : int
        A composition across a gap combines only the ``gap_beam`` (8)
        cheapest matches of each side.
    min_coverage : float
        Drop detections whose matched share of the model is below this (0.3).
    min_size : float
        Drop detections whose box is smaller than this on its longer side (24 px).
    nms_iou : float
        A detection is suppressed if its box has IoU above this with a better
        one (0.3).
    nms_nested : float or None
        With the suppression in score order (``score_pool > 0``) only: a better kept box
        that lies inside a candidate's box by at least this share of its own area does
        not suppress the candidate, so a whole object is kept beside a better-scoring part
        of it (a giraffe's neck inside the whole animal, whose IoU with it is small but
        often above ``nms_iou``). None (default): off, every overlap above ``nms_iou``
        suppresses. In ``(0, 1]``. Left out of :meth:`as_dict` when None. On ETHZ with
        Pb maps 0.8 raised the share of giraffes a kept box overlaps at IoU >= 0.5 from
        0.64 to 0.76, but the ranking still put the neck first, and the held-out mean DR
        at 0.4 FPPI fell from 0.889 to 0.841 (``benchmarks/ethz_detector_params.py``).
    box_refine : float or None
        Box refinement, after the suppression and the ranking score (0.05; None: off). The
        upright template search of each kept detection's box (:attr:`Detection.template`)
        is widened (:func:`~shapetree.detection._template.grown_fit`: the model up to
        twice the box, moved by up to 0.3 box sides); where its mean point cost is below
        the in-box fit's by more than ``box_refine``, the detection's ``bbox`` becomes
        the box of that placement, clipped to the image, and ``match_bbox`` keeps the
        match's. A detection whose box then overlaps a better-scoring one's by IoU above
        :data:`REFINE_IOU` is dropped. The score and every term of the collection
        re-scorer stay those of the match's box; only the box reported changes. A match
        that covers part of the object (a giraffe's neck and back, the legs left to
        gaps) is then reported with the whole object's box. Needs an edge map (off with
        ``contours=`` and no image). In ``[0, 1)``. On ETHZ with Pb maps
        (``benchmarks/ethz_box_refine.py``, the ranking held out) it lifts the mean DR at
        0.4 FPPI under PASCAL from 0.822 to 0.841 and leaves the 20% rule's at 0.889;
        0.05 is the value each leave-one-class-out fold picks among 0, 0.02, 0.05 and 0.1.
    score_pool : int
        Which matches the suppression keeps. ``N > 0`` (default 30): the ``N`` cheapest
        complete matches with distinct boxes (IoU at most :data:`POOL_IOU` with a
        cheaper one in the pool) are scored first, and the suppression runs in score
        order, so a whole-object match that scores better can suppress a cheaper part
        of it (a giraffe's neck and back). 0: the paper's order, cheapest first, so a box
        is suppressed by any cheaper one it overlaps, and the ``k`` kept are then
        re-ordered by their score. On ETHZ (``benchmarks/ethz_detector_params.py``) the
        value chosen inside each fold among the cost order, 30 and 100 and four other
        detector settings lifts the held-out mean DR at 0.4 FPPI from 0.836 to 0.862
        (four folds pick 30).
    upright_cost : float
        Upright prior on the *cost* (the stitching itself): a contour matched to a model
        interval of share ``f`` pays ``upright_cost * f * (1 - cos theta)``, ``theta`` the
        turn of the least-squares similarity taking the interval onto the contour
        (:mod:`shapetree.detection._upright`): nothing for a piece standing as drawn,
        ``upright_cost * f`` for one turned by a quarter, twice that upside down (0.25).
        For photos whose objects stand roughly as the model is drawn; 0 gives back the
        paper's rotation-invariant stitching, for objects at any angle. On ETHZ with Pb
        maps (``benchmarks/ethz_detector_params.py``) the value chosen inside each
        leave-one-class-out fold among 0, 0.25 and 0.5 lifts the held-out mean DR at 0.4
        FPPI from 0.889 to 0.908 (PASCAL 0.841 to 0.861); 0.25 is the choice on all five
        classes.
    weak_cost : float
        Edge evidence: a contour of mean edge strength ``s`` matched to a
        model interval of share ``f`` pays ``weak_cost * f * (1 - min(1, s /
        strong_edge))`` on top of its shape cost, so weak (texture) edges buy
        little over a gap (default 0: off; on ETHZ it did not help overall).
    strong_edge : float
        Mean edge strength that counts as full evidence (0.3).
    size_cost : float
        Absolute-size prior: a piece of ``l`` px matched to a model share
        ``f`` implies an object perimeter ``P = l / f``; it pays ``size_cost *
        f * r`` with ``r = clip(log(full_perimeter / P) / log(full_perimeter /
        min_perimeter), 0, 1)``; pieces with ``P < min_perimeter / 2`` are not
        used at all (0 disables the cost, not the cut-off) (0.5).  Shape
        costs are scale-invariant, so without this 25-40 px texture patches
        (labels, foliage) win over real objects.
    min_perimeter, full_perimeter : float
        See ``size_cost`` (120 px, 240 px; 0 disables the cut-off).  On ETHZ
        the smallest ground-truth object (an apple logo) is 58 px on its
        longer side, about 200 px around.
    border_margin : float
        Edge pixels closer than this to the image border are ignored when
        tracing contours (6 px; 0 keeps them).  Edge detectors respond to the
        picture's own frame (scan borders, painting frames, padding), and a
        boxy model such as the mug otherwise matches the whole image.
    outline_check : float
        Holistic check of the placed outline on the *ranking score* (not on
        the cost): a kept detection scores ``-outline_check * d2`` more, where
        ``d2`` is the squared full Procrustes distance (``1 - |<z, w>|^2`` of
        the centred, unit-size point sets) between the model's samples and
        where the detection places them in the image (0.4; 0 turns it off).
        Eq. (1) scores the outline triangle by triangle; this asks whether the
        placed outline as a whole still looks like the model, which penalises
        matches that bend or squash it, e.g. a giraffe draped along a table
        edge.
    frame_prior : float
        Image-relative size prior on the *ranking score* (not on the cost): a
        kept detection whose box covers a share ``r`` of the image area scores
        ``frame_prior * log(sqrt(r))`` more (at most 0), so of two equally good matches
        the one that fills more of the picture ranks first, in its image and
        across images (0.075; 0 turns it off).  It never changes the stitching;
        with the suppression in score order (``score_pool``, the default) it also
        decides which of two overlapping matches is kept, with ``score_pool=0`` only
        their order (like the two checks beside it).  It encodes
        that photographed objects tend to fill the frame.  It is off where the
        image size is unknown (``contours=`` without an image).  On ETHZ the two
        ranking terms lift the mean DR at 0.4 FPPI from 0.626 (cost alone) to
        0.756; picked on four classes and scored on the fifth, 0.750
        (``benchmarks/ethz_rescore.py``, with the cost-order suppression).
    context_check : float
        Verification on the *ranking score* (not on the cost): a kept detection
        scores ``context_check * a`` more, where ``a`` in ``[0, 1]`` is the
        shape-context agreement of the model's samples and their placement in the
        image (:func:`~shapetree.detection.context_agreement`: mean histogram
        intersection of log-polar shape contexts, in the image frame, so an upright
        placement agrees more than one on its side) (0.15; 0 turns it off).  Like
        the two terms above it never changes the stitching (see ``score_pool``).
        The weight is the one that leave-one-class-out selection on ETHZ picks most
        often, in three of five folds (0.25 standard deviations of the score per
        standard deviation of ``a``, i.e. 0.15; ``benchmarks/ethz_verify.py``).
    collection_rescore : bool
        Collection stage, used only where one model is searched over several images
        (:func:`~shapetree.detection.evaluate_ethz`, ``shapetree detect MODEL IMAGES``
        with two or more images): rank all their detections together by the
        *collection score* of the re-scorer (:func:`~shapetree.detection.rescore_collection`),
        a fixed linear form in the score, the context agreement, the outline check, the
        frame term, the coverage, the detection's margin and lead within its image, its
        colour agreement with the most confident detections of the other images and the
        upright template check of its box (:attr:`Detection.template`) (True). Its
        weights (a fit across images plus a fit of the choice within each image) were
        fitted on the ETHZ detections with Pb maps; held out (four classes fitted, the
        fifth scored, with ``upright_cost`` and ``box_refine`` chosen in each fold too) the
        mean DR at 0.4 FPPI is 0.908 with it, against 0.768 for the score alone on the
        earlier cost-order detections (README, detection section). A
        detection's own ``score`` never depends on other images. False: the collection score is
        ``score + appearance_check * g`` (below), the score alone when that is 0.
    appearance_check : float
        With ``collection_rescore=False`` only (an error otherwise: the re-scorer has
        its own colour weight): each detection's *collection score* is its score plus
        ``appearance_check * g``, where ``g`` in ``[0, 1]`` is the mean colour-histogram
        intersection of the inside of its placed outline with the
        ``appearance_reference`` most confident detections of the other images
        (``shapetree.detection._appearance``, :func:`~shapetree.detection.collection_scores`).
        0.0 by default. On ETHZ (``benchmarks/ethz_appearance.py``) leave-one-class-out
        selection on the Pb detections picks 0.4 beside the context term's default in
        four of five folds; it lifts the Pb run but not the run with the project's own
        edge map, where the re-scorer wins.
    appearance_reference : int
        Size of the reference set of the colour agreement (both forms of the
        collection stage): the best detection of each
        image by score, the ``appearance_reference`` best of those (10).
    edge_method : {"own", "gradient", "pidinet"}
        The :func:`edge_map` method used when no edge map is given ("own": the
        boundary detector on Pb's cues; "pidinet": the learned PiDiNet detector, from
        the weights file ``edge_weights``).
    edge_weights : str or None
        ``edge_method="pidinet"`` only, and required there: the path of a PiDiNet
        ``table5_*.npz`` weights file (the authors' BSDS500 checkpoints from
        ``hellozhuo/pidinet``, research use only, not shipped with shapetree).  Checked
        when the parameters are made (a clear :class:`~shapetree.ShapeTreeError` if it
        is missing, unreadable or not PiDiNet's).  Left out of :meth:`as_dict` when
        None, so the keys of results made without it do not change.
    """

    m: int = 30
    threshold: float = 0.15
    low: float | None = None
    min_length: float = 15.0
    max_turn: float = float(np.deg2rad(60.0))
    turn_window: float = 5.0
    smooth: float = 1.0
    max_contours: int = 120
    contour_spacing: float = 6.0
    contour_min_points: int = 3
    contour_max_points: int = 24
    tau: float = 12.0
    lam: float = 1.0
    gap_cost: float = 0.8
    piece_cost: float = 0.01
    table_weight: float = 3.0
    beam: int = 32
    per_end: int = 3
    max_gap: int | None = None
    gap_beam: int = 8
    min_coverage: float = 0.3
    min_size: float = 24.0
    nms_iou: float = 0.3
    nms_nested: float | None = None
    box_refine: float | None = 0.05
    score_pool: int = 30
    weak_cost: float = 0.0
    upright_cost: float = 0.25
    strong_edge: float = 0.3
    size_cost: float = 0.5
    min_perimeter: float = 120.0
    full_perimeter: float = 240.0
    border_margin: float = 6.0
    outline_check: float = 0.4
    frame_prior: float = 0.075
    context_check: float = 0.15
    collection_rescore: bool = True
    appearance_check: float = 0.0
    appearance_reference: int = 10
    edge_method: str = "own"
    edge_weights: str | None = None

    def __post_init__(self) -> None:
        for name in _NON_NEGATIVE:
            v = getattr(self, name)
            real = isinstance(v, numbers.Real) and not isinstance(v, bool)
            if not (real and np.isfinite(v) and v >= 0):
                raise ShapeTreeError(f"{name} must be a finite number >= 0, got {v!r}")
        if self.edge_method not in EDGE_METHODS:
            raise ShapeTreeError(
                f"DetectParams.edge_method must be one of {EDGE_METHODS}, got {self.edge_method!r}"
            )
        if self.edge_weights is not None:
            if not isinstance(self.edge_weights, str | os.PathLike):
                raise ShapeTreeError(
                    f"DetectParams.edge_weights must be a file path, got {self.edge_weights!r}"
                )
            object.__setattr__(self, "edge_weights", os.fspath(self.edge_weights))
        if self.edge_method in WEIGHTED_METHODS:
            from ._pidinet import check_weights

            check_weights(self.edge_weights)  # None, missing or bad: a clear ShapeTreeError
        elif self.edge_weights is not None:
            raise ShapeTreeError(
                f"DetectParams.edge_weights is for edge_method in {WEIGHTED_METHODS}, "
                f"not {self.edge_method!r}"
            )
        ac, ar = self.appearance_check, self.appearance_reference
        if (
            isinstance(ac, bool)
            or not isinstance(ac, numbers.Real)
            or not np.isfinite(ac)
            or ac < 0
        ):
            raise ShapeTreeError(
                f"DetectParams.appearance_check must be a finite number >= 0, got {ac!r}"
            )
        if isinstance(ar, bool) or not isinstance(ar, numbers.Integral) or ar < 1:
            raise ShapeTreeError(
                f"DetectParams.appearance_reference must be an integer >= 1, got {ar!r}"
            )
        if not isinstance(self.collection_rescore, bool | np.bool_):
            raise ShapeTreeError(
                f"DetectParams.collection_rescore must be True or False, got "
                f"{self.collection_rescore!r}"
            )
        object.__setattr__(self, "collection_rescore", bool(self.collection_rescore))
        if self.collection_rescore and ac > 0:
            raise ShapeTreeError(
                f"DetectParams.appearance_check={ac!r} weighs the colour agreement of the "
                "collection stage without the re-scorer; the re-scorer "
                "(collection_rescore=True, the default) has its own colour weight. Pass "
                "collection_rescore=False with it"
            )
        sp = self.score_pool
        if isinstance(sp, bool) or not isinstance(sp, numbers.Integral) or sp < 0:
            raise ShapeTreeError(f"DetectParams.score_pool must be an integer >= 0, got {sp!r}")
        br = self.box_refine
        if br is not None and (
            isinstance(br, bool)
            or not isinstance(br, numbers.Real)
            or not np.isfinite(br)
            or not 0 <= br < 1
        ):
            raise ShapeTreeError(
                f"DetectParams.box_refine must be None or a number in [0, 1), got {br!r}"
            )
        nn = self.nms_nested
        if nn is not None:
            if (
                isinstance(nn, bool)
                or not isinstance(nn, numbers.Real)
                or not np.isfinite(nn)
                or not 0 < nn <= 1
            ):
                raise ShapeTreeError(
                    f"DetectParams.nms_nested must be None or a number in (0, 1], got {nn!r}"
                )
            if sp == 0:
                raise ShapeTreeError(
                    "DetectParams.nms_nested applies to the suppression in score order; "
                    "it needs score_pool > 0 (got score_pool=0)"
                )
        lo, hi = self.contour_min_points, self.contour_max_points
        for field_name, v in (("contour_min_points", lo), ("contour_max_points", hi)):
            if isinstance(v, bool) or not isinstance(v, numbers.Integral):
                raise ShapeTreeError(f"DetectParams.{field_name} must be an integer, got {v!r}")
        if lo < 2:
            raise ShapeTreeError(
                f"DetectParams.contour_min_points must be >= 2 (an open contour is resampled "
                f"to at least its two end points), got {lo}"
            )
        if hi < lo:
            raise ShapeTreeError(
                f"DetectParams.contour_max_points ({hi}) must be >= contour_min_points ({lo})"
            )

    @property
    def collection_stage(self) -> bool:
        """Whether a collection of two or more images is ranked by its collection score
        (``collection_rescore``, or ``appearance_check > 0``)."""
        return self.collection_rescore or self.appearance_check > 0

    def as_dict(self, collection: bool = True) -> dict[str, Any]:
        """All parameters as a JSON-friendly dict (``edge_weights`` and ``nms_nested``
        only when set, so the keys of runs made before they existed stay; ``box_refine``
        always, ``None`` when off, since its default is on).

        ``DetectParams(**p.as_dict()) == p``: the ETHZ protocol's workers rebuild the
        parameters from this form.

        ``collection=False`` leaves out the collection stage's fields
        (:data:`COLLECTION_FIELDS`), which never change one image's detections: the
        keys of per-image caches are made from that form."""
        d = dataclasses.asdict(self)
        for name in ("edge_weights", "nms_nested"):
            if d[name] is None:
                del d[name]
        if not collection:
            for name in COLLECTION_FIELDS:
                del d[name]
        return d


@dataclass
class Detection:
    """One detection of the model in an image.

    Attributes
    ----------
    cost : float
        Total matching cost (model-fraction units; lower is better).
    score : float
        Ranking score, higher is better: ``-cost - outline_check * d2 +
        context_check * agreement``, plus the image-relative size prior
        ``frame_prior * log(sqrt(box share of image))`` when the image size is
        known (see :class:`DetectParams`).
    bbox : tuple of float
        ``(x1, y1, x2, y2)`` in px: box of the matched image points and of the
        gap model points mapped by the similarity fitted to the matched ones.
    model_points : ndarray, shape (m, 2)
        The model's stitching samples.
    image_points : ndarray, shape (m, 2)
        Where each model sample lands in the image (px).  Inside matched
        pieces a model sample is placed on the contour at the same arclength
        fraction as on the model subcurve; inside gaps it is the
        similarity-mapped model point.
    matched : ndarray, shape (m,), bool
        Whether the sample lies on a matched piece (True) or in a gap.
    gaps : list of (int, int, float)
        Gaps as ``(start index, end index, share of model length)``; a gap
        runs forward from ``start`` to ``end`` (model indices, cyclic).
    coverage : float
        Matched share of the model's (real) length, ``1 - sum of gap shares``.
    pieces : list of dict
        Matched contours in model order: ``contour`` (index into
        ``DetectionRun.contours``), ``reversed``, ``model_start``,
        ``model_len`` (segments), ``cost``.
    match_bbox : tuple of float or None
        Where ``DetectParams.box_refine`` replaced ``bbox`` by the box of the widened
        template fit: the box of the match (the one described under ``bbox``, which every
        ranking term is computed from). None where ``bbox`` is the match's.
    template, template_support, template_gain, box_density : float
        The upright template check of the box (:mod:`shapetree.detection._template`):
        how well the model as drawn, fitted to the box's edges by an oriented chamfer
        search, matches them (in ``[0, 1]``), the share of its points an edge supports,
        how much better it matches than the model turned on its side, and the share of
        edge pixels in the box. Terms of the collection re-scorer, not of the score; 0
        where there is no edge map (``contours=`` without an image).
    """

    cost: float
    score: float
    bbox: tuple[float, float, float, float]
    model_points: NDArray[np.float64]
    image_points: NDArray[np.float64]
    matched: NDArray[np.bool_]
    gaps: list[tuple[int, int, float]]
    coverage: float
    pieces: list[dict[str, Any]] = field(default_factory=list)
    template: float = 0.0
    template_support: float = 0.0
    template_gain: float = 0.0
    box_density: float = 0.0
    match_bbox: tuple[float, float, float, float] | None = None

    @property
    def match_box(self) -> tuple[float, float, float, float]:
        """The box of the match: ``match_bbox`` where the box was refined, else ``bbox``."""
        return self.bbox if self.match_bbox is None else self.match_bbox

    def to_json(self) -> dict[str, Any]:
        """JSON-friendly dict (lists of floats; ``match_bbox`` only where the box was
        refined)."""
        doc = {
            "score": float(self.score),
            "cost": float(self.cost),
            "bbox": [float(v) for v in self.bbox],
            "coverage": float(self.coverage),
            "model_points": np.round(self.model_points, 3).tolist(),
            "image_points": np.round(self.image_points, 3).tolist(),
            "matched": [bool(v) for v in self.matched],
            "gaps": [[int(a), int(b), float(f)] for a, b, f in self.gaps],
            "pieces": [dict(p) for p in self.pieces],
            **{t: float(getattr(self, t)) for t in TEMPLATE_TERMS},
        }
        if self.match_bbox is not None:
            doc["match_bbox"] = [float(v) for v in self.match_bbox]
        return doc


@dataclass
class DetectionRun:
    """Everything :func:`detect_detailed` computed (for pictures and timing).

    Attributes
    ----------
    detections : list of Detection
    edges : ndarray, shape (H, W)
    contours : list of ndarray, each (n_i, 2)
        Traced contours (1-px resampled polylines) used for matching.
    model : DetectionModel
    timings : dict of str to float
        Seconds spent in ``edges``, ``contours``, ``tables``, ``stitch``,
        ``select``.
    params : DetectParams
    """

    detections: list[Detection]
    edges: NDArray[np.float64]
    contours: list[NDArray[np.float64]]
    model: DetectionModel
    timings: dict[str, float]
    params: DetectParams


def _box_iou(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """IoU of one box ``a`` (4,) with boxes ``b`` (n, 4)."""
    ix = np.clip(np.minimum(a[2], b[:, 2]) - np.maximum(a[0], b[:, 0]), 0, None)
    iy = np.clip(np.minimum(a[3], b[:, 3]) - np.maximum(a[1], b[:, 1]), 0, None)
    inter = ix * iy
    area_a = max(a[2] - a[0], 0.0) * max(a[3] - a[1], 0.0)
    area_b = np.clip(b[:, 2] - b[:, 0], 0, None) * np.clip(b[:, 3] - b[:, 1], 0, None)
    return inter / np.maximum(area_a + area_b - inter, 1e-9)


def _fit_similarity(src: NDArray, dst: NDArray) -> tuple[complex, complex]:
    """Least-squares similarity ``dst ~ alpha * src + beta`` (complex numbers)."""
    zs = src[:, 0] + 1j * src[:, 1]
    zd = dst[:, 0] + 1j * dst[:, 1]
    ms, md = zs.mean(), zd.mean()
    a, b = zs - ms, zd - md
    den = np.sum(np.abs(a) ** 2)
    alpha = np.sum(np.conj(a) * b) / den if den > 1e-12 else 1.0 + 0j
    return complex(alpha), complex(md - alpha * ms)


def _reconstruct(
    res: Any,
    e: int,
    total_cost: float,
    model: DetectionModel,
    dense: list[NDArray[np.float64]],
    piece_costs: NDArray[np.float64],
) -> Detection:
    m = res.m
    pieces = res.pieces(e)
    pts = model.points
    img = np.full((m, 2), np.nan)
    matched = np.zeros(m, bool)
    seg = np.hypot(*(np.roll(pts, -1, axis=0) - pts).T)
    out_pieces = []
    for d, a, L in pieces:
        ci, rev = d // 2, bool(d % 2)
        poly = dense[ci][::-1] if rev else dense[ci]
        idx = (a + np.arange(L + 1)) % m
        s = np.concatenate([[0.0], np.cumsum(seg[idx[:-1]])])
        s = s / s[-1] if s[-1] > 0 else np.linspace(0, 1, L + 1)
        pseg = np.hypot(*np.diff(poly, axis=0).T)
        pc = np.concatenate([[0.0], np.cumsum(pseg)])
        pc = pc / pc[-1] if pc[-1] > 0 else np.linspace(0, 1, len(poly))
        img[idx, 0] = np.interp(s, pc, poly[:, 0])
        img[idx, 1] = np.interp(s, pc, poly[:, 1])
        matched[idx] = True
        out_pieces.append(
            {
                "contour": int(ci),
                "reversed": rev,
                "model_start": int(a),
                "model_len": int(L),
                "cost": float(piece_costs[d, a, L]),
            }
        )
    # gap segments: model segment i (i -> i+1) is in a gap unless inside a piece
    seg_matched = np.zeros(m, bool)
    for _d, a, L in pieces:
        seg_matched[(a + np.arange(L)) % m] = True
    gaps: list[tuple[int, int, float]] = []
    if not seg_matched.all():
        start = int(np.flatnonzero(seg_matched)[-1] + 1) % m if seg_matched.any() else 0
        i = 0
        while i < m:
            j = (start + i) % m
            if not seg_matched[j]:
                g0 = j
                share = 0.0
                while i < m and not seg_matched[(start + i) % m]:
                    share += float(model.gap_weight[(start + i) % m])
                    i += 1
                gaps.append((g0, (start + i) % m, share))
            else:
                i += 1
    alpha, beta = _fit_similarity(pts[matched], img[matched])
    zg = alpha * (pts[~matched, 0] + 1j * pts[~matched, 1]) + beta
    img[~matched, 0] = zg.real
    img[~matched, 1] = zg.imag
    box = (
        float(img[:, 0].min()),
        float(img[:, 1].min()),
        float(img[:, 0].max()),
        float(img[:, 1].max()),
    )
    coverage = 1.0 - sum(g[2] for g in gaps)
    return Detection(
        cost=float(total_cost),
        score=-float(total_cost),
        bbox=box,
        model_points=pts.copy(),
        image_points=img,
        matched=matched,
        gaps=gaps,
        coverage=float(coverage),
        pieces=out_pieces,
    )


def _evidence_costs(
    p: DetectParams,
    frac: NDArray[np.float64],
    strengths: NDArray[np.float64],
    lengths: list[float],
) -> NDArray[np.float64]:
    """Edge-strength and absolute-size terms of each piece, shape ``(2 n, m, m)``.

    ``frac[a, L]`` is the model share of interval ``(a, L)``; both directions
    of a contour get the same terms (see ``weak_cost`` and ``size_cost`` in
    :class:`DetectParams`).
    """
    s = np.repeat(np.asarray(strengths, dtype=np.float64), 2)
    ln = np.repeat(np.asarray(lengths, dtype=np.float64), 2)
    out = np.zeros((len(s),) + frac.shape)
    if p.weak_cost > 0:
        weak = 1.0 - np.minimum(1.0, s / max(p.strong_edge, 1e-9))
        out += p.weak_cost * weak[:, None, None] * frac[None]
    with np.errstate(divide="ignore", invalid="ignore"):
        perim = ln[:, None, None] / frac[None]  # inf where frac = 0 (column L = 0)
        if p.size_cost > 0 and p.full_perimeter > p.min_perimeter > 0:
            r = np.log(p.full_perimeter / perim) / np.log(p.full_perimeter / p.min_perimeter)
            out += p.size_cost * frac[None] * np.clip(r, 0.0, 1.0)
    if p.min_perimeter > 0:
        out[perim < 0.5 * p.min_perimeter] = np.inf
    return out


def _without_border(e: NDArray[np.float64], margin: float) -> NDArray[np.float64]:
    """``e`` with the edge strength within ``margin`` px of the image border set to 0."""
    b = int(np.ceil(margin))
    if b <= 0:
        return e
    out = e.copy()
    out[:b] = 0.0
    out[-b:] = 0.0
    out[:, :b] = 0.0
    out[:, -b:] = 0.0
    return out


def frame_term(bbox: ArrayLike, shape: tuple[int, ...]) -> float:
    """``log(sqrt(r))`` for a box covering a share ``r`` of an image of ``shape`` (<= 0).

    The quantity :attr:`DetectParams.frame_prior` weighs.
    """
    x1, y1, x2, y2 = (float(v) for v in bbox)
    area = max(x2 - x1, 1.0) * max(y2 - y1, 1.0)
    return 0.5 * float(np.log(min(area / float(shape[0] * shape[1]), 1.0)))


def _ranking_score(det: Detection, shape: tuple[int, ...] | None, p: DetectParams) -> Detection:
    """``det`` with the ranking terms of ``p`` (outline check, frame prior, context check)."""
    score = -det.cost
    if p.outline_check:
        score -= p.outline_check * outline_dif(det.model_points, det.image_points)
    if p.frame_prior and shape is not None:
        score += p.frame_prior * frame_term(det.bbox, shape)
    if p.context_check:
        try:
            score += p.context_check * context_agreement(det.model_points, det.image_points)
        except ShapeTreeError:  # a placement whose points all coincide agrees in nothing
            pass
    return dataclasses.replace(det, score=score)


def _as_contour(contour: object, name: str) -> NDArray[np.float64]:
    """One given image contour as an open ``(n, 2)`` polyline (a finite float64 copy).

    It may be in any form :func:`shapetree.curves.as_curve` accepts: an ``(n, 2)`` array; an
    OpenCV contour ``(n, 1, 2)``; or a geometry with a ``__geo_interface__`` (a
    ``LineString``; a ``Polygon``'s exterior, a ``LinearRing``). The polyline runs through
    the points as given, first to last: a ring's repeated closing point is dropped, so its
    closing segment is not part of it, as OpenCV gives closed boundaries (a contour that
    ends where it starts has no shape-tree and would never be matched). Duplicate points
    are kept; a contour may have zero length (the caller skips it).
    """
    return _as_xy(contour, name)


def _as_contours(contours: object) -> list[NDArray[np.float64]]:
    """A list of image contours, each read by :func:`_as_contour`.

    Refuses one contour given in place of the list (iterating it would give its points).
    """
    single = (
        isinstance(contours, np.ndarray)
        and (contours.ndim == 2 or (contours.ndim == 3 and contours.shape[1:] == (1, 2)))
    ) or hasattr(contours, "__geo_interface__")
    if single or isinstance(contours, str | Mapping):
        what = (
            f"an array of shape {contours.shape}"
            if isinstance(contours, np.ndarray)
            else f"a {type(contours).__name__}"
        )
        raise ShapeTreeError(
            f"contours= takes a list of contours, got {what}; for a single contour "
            f"pass [contour]. Each contour is {ACCEPTED_FORMS}"
        )
    return [_as_contour(c, f"contours[{i}]") for i, c in enumerate(contours)]


def _given_contours(contours: object) -> list[NDArray[np.float64]]:
    """The ``contours=`` of :func:`detect_detailed`, each as a 1-px resampled polyline.

    Contours of zero length (a single point, as ``cv2.findContours`` returns for a speck,
    or repeated copies of one point) carry no shape and are skipped.
    """
    dense = []
    for c in _as_contours(contours):
        length = polyline_length(c) if len(c) > 1 else 0.0
        if length > 0:
            dense.append(resample(c, max(2, int(np.ceil(length)) + 1), closed=False))
    return dense


def _as_image(image: ArrayLike | str | os.PathLike[str] | None) -> NDArray | None:
    if image is None:
        return None
    if isinstance(image, (str, os.PathLike)):
        return load_image(image)
    return np.asarray(image)


def detect_detailed(
    model: DetectionModel | ArrayLike | str | os.PathLike[str],
    image: ArrayLike | str | os.PathLike[str] | None,
    *,
    edges: ArrayLike | str | os.PathLike[str] | None = None,
    k: int = 5,
    params: DetectParams | None = None,
    contours: list[ArrayLike] | None = None,
    **overrides: Any,
) -> DetectionRun:
    """Like :func:`detect`, but also return edges, contours and timings.

    ``contours`` (a list of open polylines in px, in any form :func:`detect`
    accepts) replaces edge detection and tracing when given; ``image`` and
    ``edges`` may then be None.
    """
    p = params or DetectParams()
    if overrides:
        p = dataclasses.replace(p, **overrides)
    if k < 1:
        raise ShapeTreeError(f"k must be >= 1, got {k}")
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    if isinstance(model, DetectionModel):
        mdl = model  # its own sampling wins over ``params.m``
        p = dataclasses.replace(p, m=len(model.points))
    else:
        mdl = load_model(model, m=p.m)
    img = _as_image(image)
    e = _edge_input(img, edges, contours is not None, p)
    timings["edges"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    if contours is not None:
        dense = _given_contours(contours)
        strengths = [1.0] * len(dense)  # given contours count as full edge evidence
    else:
        traced: list[TracedContour] = trace_contours_detailed(
            _without_border(e, p.border_margin),
            threshold=p.threshold,
            low=p.low,
            min_length=p.min_length,
            max_turn=p.max_turn,
            turn_window=p.turn_window,
            smooth=p.smooth,
        )[: p.max_contours]
        dense = [t.points for t in traced]
        strengths = [t.strength for t in traced]
    timings["contours"] = time.perf_counter() - t0
    run = DetectionRun([], e, dense, mdl, timings, p)
    if not dense:
        timings["tables"] = timings["stitch"] = timings["select"] = 0.0
        return run

    t0 = time.perf_counter()
    sampled = []
    for c in dense:
        n = int(round(polyline_length(c) / p.contour_spacing)) + 1
        n = int(np.clip(n, p.contour_min_points, p.contour_max_points))
        sampled.append(resample(c, n, closed=False))
    tables = contour_tables(sampled, mdl.points)
    timings["tables"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    base = _piece_costs(p, mdl.points, tables, strengths, dense)
    res = _stitch_contours(p, mdl, base, dense)
    timings["stitch"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    run.detections = _select(p, res, mdl, dense, base, e, k)
    timings["select"] = time.perf_counter() - t0
    return run


def _edge_input(
    img: NDArray[np.float64] | None,
    edges: ArrayLike | str | os.PathLike[str] | None,
    given_contours: bool,
    p: DetectParams,
) -> NDArray[np.float64]:
    """The edge map a detection traces: computed from the image (``p.edge_method``), read
    from a file, or given; an empty map of the image's size when contours are given."""
    if given_contours:
        e = np.zeros(img.shape[:2]) if img is not None else np.zeros((0, 0))
    elif edges is None:
        if img is None:
            raise ImageError("detect needs an image or an edge map")
        e = edge_map(img, method=p.edge_method, weights=p.edge_weights)
    elif isinstance(edges, (str, os.PathLike)):
        e = load_edges(edges)
    else:
        e = np.clip(np.asarray(edges, dtype=np.float64), 0.0, 1.0)
    if e.ndim != 2:
        raise ImageError(f"edge map must be 2-D, got shape {e.shape}")
    if not given_contours and img is not None and img.shape[:2] != e.shape:
        raise ImageError(f"edge map shape {e.shape} differs from image shape {img.shape[:2]}")
    return e


def _piece_costs(
    p: DetectParams,
    mpts: NDArray[np.float64],
    tables: NDArray[np.float64],
    strengths: list[float],
    dense: list[NDArray[np.float64]],
) -> NDArray[np.float64]:
    """``base[d, a, L]``: the cost of matching contour ``d`` (both directions, ``2 nc``
    rows) to the model subcurve of ``L`` segments from sample ``a``: the weighted
    section 3 table scaled by the subcurve's share of the model, a per-piece cost and
    the evidence terms; ``L = 0`` is impossible."""
    m = p.m
    seg = np.hypot(*(np.roll(mpts, -1, axis=0) - mpts).T)
    cum = np.concatenate([[0.0], np.cumsum(np.concatenate([seg, seg]))])
    idx = np.arange(m)[:, None] + np.arange(m)[None, :]
    frac = (cum[idx] - cum[np.arange(m)][:, None]) / seg.sum()
    with np.errstate(invalid="ignore"):
        base = p.table_weight * frac[None] * tables + p.piece_cost
    base += _evidence_costs(p, frac, np.asarray(strengths), [polyline_length(c) for c in dense])
    if p.upright_cost > 0:
        base += p.upright_cost * frac[None] * (1.0 - piece_turn_cos(mpts, dense))
    base[:, :, 0] = np.inf
    return base


def _stitch_contours(
    p: DetectParams,
    mdl: DetectionModel,
    base: NDArray[np.float64],
    dense: list[NDArray[np.float64]],
) -> Any:
    """Run the stitching DP over the contours, each a piece in both directions (its two
    ends, its box) with the piece costs ``base``."""
    nc = len(dense)
    ends = np.empty((2 * nc, 2))
    ends[0::2] = [c[0] for c in dense]
    ends[1::2] = [c[-1] for c in dense]
    piece_p = np.empty(2 * nc, np.int64)
    piece_q = np.empty(2 * nc, np.int64)
    piece_p[0::2], piece_q[0::2] = 2 * np.arange(nc), 2 * np.arange(nc) + 1
    piece_p[1::2], piece_q[1::2] = 2 * np.arange(nc) + 1, 2 * np.arange(nc)
    boxes = np.array([[c[:, 0].min(), c[:, 1].min(), c[:, 0].max(), c[:, 1].max()] for c in dense])
    return run_stitch(
        mdl.points,
        mdl.gap_weight,
        base,
        piece_p,
        piece_q,
        np.repeat(np.arange(nc), 2),
        np.repeat(boxes, 2, axis=0),
        ends,
        tau=p.tau,
        lam=p.lam,
        gap_cost=p.gap_cost,
        beam=p.beam,
        per_end=p.per_end,
        max_gap=p.max_gap if p.max_gap is not None else p.m // 2,
        gap_beam=p.gap_beam,
    )


def _select(
    p: DetectParams,
    res: Any,
    mdl: DetectionModel,
    dense: list[NDArray[np.float64]],
    base: NDArray[np.float64],
    e: NDArray[np.float64],
    k: int,
) -> list[Detection]:
    """Up to ``k`` detections from the complete matches: each reconstructed, dropped if
    too small or covering too little of the model, suppressed by a kept box (cheapest
    first, or in score order with ``score_pool``); then ranked by their score, with the
    template check of each box."""
    ids, costs = complete_matches(res)
    shape = e.shape if e.size else None
    if p.score_pool:
        pool = _distinct_matches(p, res, ids, costs, mdl, dense, base, p.score_pool, POOL_IOU)
        pool = [_ranking_score(d, shape, p) for d in pool]
        pool.sort(key=lambda d: -d.score)
        kept = _suppress(pool, p.nms_iou, k, p.nms_nested)
    else:
        kept = _distinct_matches(p, res, ids, costs, mdl, dense, base, k, p.nms_iou)
        kept = [_ranking_score(d, shape, p) for d in kept]
    if kept and e.size:
        fields = template_fields(e, p.threshold)
        tm = template_model(kept[0].model_points)
        kept = [dataclasses.replace(d, **template_terms(fields, tm, d.bbox)) for d in kept]
        if p.box_refine is not None:
            kept = _refine_boxes(kept, fields, tm, p.box_refine, e.shape)
    kept.sort(key=lambda d: -d.score)
    return kept


#: ``box_refine``: a detection whose refined box overlaps a better-scoring one's by more
#: than this IoU is dropped (two matches of one object, grown to the same box)
REFINE_IOU = 0.5


def refine_plan(
    scores: ArrayLike,
    boxes: ArrayLike,
    template: ArrayLike,
    grown_cost: ArrayLike,
    grown_box: ArrayLike,
    delta: float,
    shape: tuple[int, ...],
) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_]]:
    """The box refinement of one image's kept detections (``DetectParams.box_refine``).

    Parameters
    ----------
    scores : array_like, shape (n,)
        Their ranking scores (the duplicates are dropped in this order, best first).
    boxes : array_like, shape (n, 4)
        Their match boxes ``(x1, y1, x2, y2)`` (px).
    template : array_like, shape (n,)
        Their ``template`` terms (1 - the in-box fit's mean point cost).
    grown_cost, grown_box : array_like, shapes (n,) and (n, 4)
        :func:`~shapetree.detection._template.grown_fit` of each box.
    delta : float
        ``box_refine``: how much lower the widened fit's cost must be.
    shape : tuple of int
        ``(H, W)`` of the image (the refined boxes are clipped to it).

    Returns
    -------
    box : ndarray, shape (n, 4)
        Each detection's box, refined or its match box.
    refined : ndarray, shape (n,), bool
        Whether it was refined.
    keep : ndarray, shape (n,), bool
        False for a detection whose box overlaps a better-scoring kept one's by IoU above
        :data:`REFINE_IOU`.
    """
    h, w = shape[:2]
    box = np.array(boxes, dtype=np.float64).reshape(-1, 4)
    grown = np.asarray(grown_box, dtype=np.float64).reshape(-1, 4)
    better = (1.0 - np.asarray(template, float)) - np.asarray(grown_cost, float) > delta
    clipped = np.c_[np.maximum(grown[:, :2], 0.0), np.minimum(grown[:, 2:], [w, h])]
    refined = better & (clipped[:, 2] > clipped[:, 0]) & (clipped[:, 3] > clipped[:, 1])
    box[refined] = clipped[refined]
    keep = np.zeros(len(box), bool)
    for i in np.argsort(-np.asarray(scores, float), kind="stable"):
        if keep.any() and np.any(_box_iou(box[i], box[keep]) > REFINE_IOU):
            continue
        keep[i] = True
    return box, refined, keep


def _refine_boxes(
    kept: list[Detection], fields: Any, tm: Any, delta: float, shape: tuple[int, ...]
) -> list[Detection]:
    """``kept`` with the boxes of :func:`refine_plan` (``DetectParams.box_refine``)."""
    fits = [grown_fit(fields, tm, d.bbox) for d in kept]
    box, refined, keep = refine_plan(
        [d.score for d in kept],
        [d.bbox for d in kept],
        [d.template for d in kept],
        [c for c, _ in fits],
        [b for _, b in fits],
        delta,
        shape,
    )
    return [
        dataclasses.replace(d, bbox=tuple(float(v) for v in b), match_bbox=d.bbox) if r else d
        for d, b, r, k in zip(kept, box, refined, keep, strict=True)
        if k
    ]


#: ``score_pool``: matches whose boxes overlap a cheaper one in the pool by more than this
#: IoU are near-duplicates (the same contours, one piece longer or shorter) and left out
POOL_IOU = 0.7


def _distinct_matches(
    p: DetectParams,
    res: Any,
    ids: NDArray[np.int64],
    costs: NDArray[np.float64],
    mdl: DetectionModel,
    dense: list[NDArray[np.float64]],
    base: NDArray[np.float64],
    k: int,
    iou: float,
) -> list[Detection]:
    """Up to ``k`` complete matches, cheapest first, each reconstructed, dropped if too
    small or covering too little of the model or if its box overlaps a kept one by IoU
    above ``iou``."""
    kept: list[Detection] = []
    kept_boxes = np.zeros((0, 4))
    # the contour boxes of all complete matches, screened at once: too small, or
    # overlapping a kept detection (the IoU is symmetric, so each kept box updates the
    # screen of every candidate in one call)
    cand_boxes = res.box[ids]
    wide = cand_boxes[:, 2:] - cand_boxes[:, :2]
    screened = np.maximum(wide[:, 0], wide[:, 1]) < p.min_size
    for t, (e_id, c) in enumerate(zip(ids, costs, strict=True)):
        if screened[t]:
            continue
        det = _reconstruct(res, int(e_id), float(c), mdl, dense, base)
        if det.coverage < p.min_coverage:
            continue
        b = np.asarray(det.bbox)
        if max(b[2] - b[0], b[3] - b[1]) < p.min_size:
            continue
        if len(kept) and np.any(_box_iou(b, kept_boxes) > iou):
            continue
        kept.append(det)
        kept_boxes = np.vstack([kept_boxes, b])
        if len(kept) >= k:
            break
        screened |= _box_iou(b, cand_boxes) > iou
    return kept


def _inside_share(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Share of the area of each box of ``b`` (n, 4) that lies inside box ``a`` (4,)."""
    ix = np.clip(np.minimum(a[2], b[:, 2]) - np.maximum(a[0], b[:, 0]), 0, None)
    iy = np.clip(np.minimum(a[3], b[:, 3]) - np.maximum(a[1], b[:, 1]), 0, None)
    area_b = np.clip(b[:, 2] - b[:, 0], 0, None) * np.clip(b[:, 3] - b[:, 1], 0, None)
    return ix * iy / np.maximum(area_b, 1e-9)


def _suppress(
    ranked: list[Detection], iou: float, k: int, nested: float | None = None
) -> list[Detection]:
    """Greedy suppression in the given order: up to ``k`` detections, none overlapping an
    earlier kept one by IoU above ``iou``, except (``nested``) a kept one that lies inside
    it by at least that share of its area."""
    kept: list[Detection] = []
    for det in ranked:
        b = np.asarray(det.bbox)
        if kept:
            boxes = np.array([d.bbox for d in kept])
            over = _box_iou(b, boxes) > iou
            if nested is not None:
                over &= _inside_share(b, boxes) < nested
            if np.any(over):
                continue
        kept.append(det)
        if len(kept) >= k:
            break
    return kept


def detect(
    model: DetectionModel | ArrayLike | str | os.PathLike[str],
    image: ArrayLike | str | os.PathLike[str] | None,
    *,
    edges: ArrayLike | str | os.PathLike[str] | None = None,
    k: int = 5,
    params: DetectParams | None = None,
    contours: list[ArrayLike] | None = None,
    **overrides: Any,
) -> list[Detection]:
    """Find the ``k`` best non-overlapping matches of a deformable model in an image.

    Stages (paper §4): soft edge map -> contours -> contour-vs-model tables
    (§3 kernel) -> stitching DP with gaps -> complete matches, ranked by cost,
    greedy non-maximum suppression on boxes.

    Parameters
    ----------
    model : DetectionModel, path-like or array_like, shape (n, 2)
        The model: a :class:`DetectionModel`, an outline drawing or point file
        (see :func:`load_model`), or closed-curve points in any form
        :func:`shapetree.curves.as_curve` accepts (an OpenCV contour ``(n, 1,
        2)``, a shapely ``Polygon``: its exterior, ...).
    image : array_like, shape (H, W) or (H, W, 3), path-like, or None
        The image (may be None when ``edges`` is given).
    edges : array_like, shape (H, W), path-like, or None
        Soft edge map in ``[0, 1]`` (e.g. an ETHZ Pb map); computed with
        :func:`edge_map` when None.
    k : int
        Maximum number of detections returned (default 5).
    params : DetectParams or None
        Parameters; keyword ``overrides`` replace single fields.
    contours : list of array_like, each shape (n_i, 2), or None
        Use these open image contours (px) instead of tracing the edge map.
        Each may be an ``(n_i, 2)`` array, an OpenCV contour ``(n_i, 1, 2)``
        (e.g. the list ``cv2.findContours`` returns), or a geometry with a
        ``__geo_interface__`` (a ``LineString``; a ``Polygon``: its exterior;
        a ``LinearRing``).  Each is the open polyline through its points, first
        to last: a closed boundary (an OpenCV contour, a ring, whose repeated
        closing point is dropped) does not include its closing segment.
        Contours of zero length (single points) are skipped.

    Returns
    -------
    list of Detection
        At most ``k``, best (lowest cost) first; boxes overlap by at most
        ``nms_iou`` IoU.

    Raises
    ------
    ImageError
        For unreadable or mismatched image / edge inputs.
    ShapeTreeError
        For bad parameters or models, or a contour in none of the accepted
        forms (a :class:`~shapetree.CurveError` naming ``contours[i]`` and the
        forms).
    """
    return detect_detailed(
        model, image, edges=edges, k=k, params=params, contours=contours, **overrides
    ).detections
