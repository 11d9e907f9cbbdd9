"""The collection re-scorer: one ranking of every detection of a collection.

A detection's ranking score (:class:`~shapetree.detection.DetectParams`) is the stitched
cost with three checks added, and it judges the detection by its own image alone. Where
one model is searched over several photos, this module ranks all their detections
together by a fixed linear form in the twelve terms of each detection below, the
**collection score**, in the units of the score:

``collection_score = base + sum_t RESCORER_WEIGHTS[t] * t``

=============  =====================================================================
term           what it is
=============  =====================================================================
base           the detection's score less ``context_check * context`` (the score of
               a run without the context check)
context        shape-context agreement of the placed outline
               (:func:`~shapetree.detection.context_agreement`, in ``[0, 1]``)
outline_dif    squared Procrustes distance of the model samples and their placement
               (:func:`shapetree.geometry.outline_dif`, the ``outline_check`` term)
frame          ``log(sqrt(box share of the image))`` (<= 0, the ``frame_prior`` term)
coverage       share of the model outline matched by real contours, not gaps
margin         ``base`` less the best ``base`` of the same image (<= 0)
lead           for an image's best detection, its ``base`` lead over the second; 0
               for the others and for an image's only detection
appearance     colour agreement with the most confident detections of the other
               images (:func:`~shapetree.detection.appearance_agreement`)
template       the upright template check of the box (:mod:`._template`): how well the
               model as drawn, fitted to the box's edges by an oriented chamfer search,
               matches them, in ``[0, 1]``
template_      at that fit, the share of model points an edge supports
support
template_gain  ``template`` less the same fit with the model turned on its side
box_density    share of edge pixels inside the box
=============  =====================================================================

The weights are the sum of two fits on the ETHZ Shape Classes run with the Pb edge maps
(5 hand-drawn models x 255 images, up to 5 kept detections each, suppressed in score
order: ``DetectParams.score_pool`` 30, stitched with the upright prior
``DetectParams.upright_cost`` 0.25, boxes not refined), a detection being right where it overlaps a
ground-truth box by IoU >= 0.2:

- the **global** fit, a logistic regression over every detection on the standardised
  terms: it tells right from wrong across all photos at once. Its term set (the first
  eight and ``template_support``) and L2 penalty (10000) were chosen by leave-one-class-out
  over the five classes among eight candidate sets (``benchmarks/ethz_template.py``);
- the **within** fit, a conditional logit over each photo's detections of one model (a
  softmax over them; the likelihood is the mass on its right ones), on all twelve terms
  standardised, L2 1: which of one photo's places is the object, given that it holds one;
- added as ``global / sd(global) + 2 * within / sd(within)`` (each in units of its standard
  deviation over the detections), which is one linear form in the terms: the weights here,
  per unit of each term, scaled so that ``base`` weighs 1 (a ranking is unchanged by a
  common scale and by the intercept). The combination (``sum_2`` among ``global``, a
  permutation of each photo's scores and sums with 0.25 to 2) and the within penalty were
  chosen by leave-one-class-out over the five classes.

``python3 benchmarks/ethz_within_image.py --rows <rows of ethz_template.py>`` writes them
(``fit_all`` in ``benchmarks/results/ethz_within_image_pb_upright_0.25.json``). Held out
(mean DR at 0.4 FPPI, 20% rule / PASCAL), every choice above made inside each fold on four
classes and the fifth scored, the boxes not refined: 0.8814 / 0.8164 on these detections,
0.9050 / 0.8408 on those of ``upright_cost`` 0.5, 0.8886 / 0.8224 on those without the
upright prior (the release before, ``ethz_within_image_pb.json``); with the boxes refined
and the detector's ``upright_cost`` chosen inside each fold too, 0.9081 / 0.8607
(``benchmarks/ethz_detector_params.py``, ``ethz_detector_params_upright_pb.json``).

It is transductive through ``appearance`` (the other photos, never their labels) and
through ``margin`` / ``lead`` (the other detections of the same photo). A detection's own
``score`` never changes.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping, Sequence
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from shapetree._errors import ShapeTreeError
from shapetree.geometry import outline_dif

from ._template import TEMPLATE_TERMS
from ._verify import context_agreement

if TYPE_CHECKING:
    from ._detect import DetectParams

__all__ = ["RESCORER_WEIGHTS", "detection_terms", "rescore_collection"]

#: Weight of each term of the collection score per unit of the term, ``base`` = 1 (see
#: the module docstring for where they come from).
RESCORER_WEIGHTS: Mapping[str, float] = MappingProxyType(
    {
        "context": 1.1583,
        "outline_dif": -0.2441,
        "frame": 0.2436,
        "coverage": 0.8827,
        "margin": 0.1792,
        "lead": 4.1377,
        "appearance": 2.0423,
        "template": 1.4640,
        "template_support": 1.1139,
        "template_gain": 0.8713,
        "box_density": -3.6314,
    }
)

#: the terms :func:`detection_terms` gives (one detection, its image alone)
DETECTION_TERMS = ("context", "outline_dif", "frame", "coverage")
#: the terms a detection record carries from its image's edge map (the upright template
#: check, :mod:`._template`)
RECORD_TERMS = TEMPLATE_TERMS


def detection_terms(
    model_points: ArrayLike,
    image_points: ArrayLike,
    bbox: Sequence[float],
    coverage: float,
    image_shape: Sequence[int],
) -> dict[str, float]:
    """The re-scorer's terms of one detection that need only its own image.

    Parameters
    ----------
    model_points : array_like, shape (m, 2)
        The model's samples.
    image_points : array_like, shape (m, 2)
        Their placement in the image (px).
    bbox : sequence of 4 floats
        ``(x1, y1, x2, y2)`` of the placement (px).
    coverage : float
        Share of the model outline matched by real contours, in ``[0, 1]``.
    image_shape : sequence of int
        ``(H, W)`` of the image (px).

    Returns
    -------
    dict
        ``context``, ``outline_dif``, ``frame`` and ``coverage`` (see the module
        docstring). A placement whose points all coincide has context 0.
    """
    from ._detect import frame_term

    try:
        ctx = context_agreement(model_points, image_points)
    except ShapeTreeError:  # all points coincide: it agrees in nothing
        ctx = 0.0
    return {
        "context": float(ctx),
        "outline_dif": float(outline_dif(model_points, image_points)),
        "frame": frame_term(bbox, tuple(image_shape)),
        "coverage": float(coverage),
    }


def _margins_and_leads(keys: Sequence[Hashable], base: np.ndarray) -> tuple[np.ndarray, ...]:
    """``margin`` and ``lead`` of every detection from the bases of its image's."""
    margin, lead = np.zeros(len(keys)), np.zeros(len(keys))
    groups: dict[Hashable, list[int]] = {}
    for i, k in enumerate(keys):
        groups.setdefault(k, []).append(i)
    for idx in groups.values():
        b = base[idx]
        order = np.argsort(-b, kind="stable")
        margin[idx] = b - b[order[0]]
        if len(idx) > 1:
            lead[idx[order[0]]] = b[order[0]] - b[order[1]]
    return margin, lead


def rescore_collection(
    image_keys: Sequence[Hashable],
    scores: ArrayLike,
    terms: Mapping[str, ArrayLike],
    context_check: float,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The collection score of every detection of a collection.

    Parameters
    ----------
    image_keys : sequence, length N
        The image each detection belongs to (any hashable key).
    scores : array_like, shape (N,)
        Each detection's own ranking score.
    terms : mapping
        ``context``, ``outline_dif``, ``frame``, ``coverage`` (:func:`detection_terms`),
        the four template terms (:attr:`Detection.template`) and ``appearance``
        (:func:`~shapetree.detection.appearance_agreement`), each an array of shape (N,).
    context_check : float
        The ``DetectParams.context_check`` the scores were made with (their ``base`` is
        ``score - context_check * context``).

    Returns
    -------
    collection_score : ndarray, shape (N,)
        ``base + sum_t RESCORER_WEIGHTS[t] * t`` (higher is better).
    table : dict of ndarray, shape (N,)
        Every term, ``base``, ``margin`` and ``lead`` included.

    Raises
    ------
    ShapeTreeError
        A term missing, arrays of different lengths, or NaN / infinite values.
    """
    keys = list(image_keys)
    n = len(keys)
    s = np.asarray(scores, dtype=np.float64)
    missing = [t for t in (*DETECTION_TERMS, *RECORD_TERMS, "appearance") if t not in terms]
    if missing:
        raise ShapeTreeError(f"rescore_collection: terms {missing} missing")
    table: dict[str, Any] = {t: np.asarray(terms[t], dtype=np.float64) for t in terms}
    for name, v in (("scores", s), *table.items()):
        if v.shape != (n,):
            raise ShapeTreeError(
                f"rescore_collection: {n} image keys but {name} has shape {v.shape}"
            )
        if not np.isfinite(v).all():
            raise ShapeTreeError(f"rescore_collection: NaN or infinite values in {name}")
    table["base"] = s - float(context_check) * table["context"]
    table["margin"], table["lead"] = _margins_and_leads(keys, table["base"])
    total = table["base"].copy()
    for t, w in RESCORER_WEIGHTS.items():
        total += w * table[t]
    return total, table


def collection_table(
    image_keys: Sequence[Hashable],
    detections: Sequence[Mapping[str, Any]],
    model_points: ArrayLike,
    image_shapes: Mapping[Hashable, Sequence[int]],
    histograms: ArrayLike,
    params: DetectParams,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The collection stage of ``params`` over the detections of one model.

    Parameters
    ----------
    image_keys : sequence, length N
        The image of each detection.
    detections : sequence of mapping, length N
        Each with ``score``, ``bbox``, ``coverage``, ``image_points`` and the four
        template terms (as in a :meth:`Detection.to_json` record; its ``match_bbox``, where
        there is one, is the box the terms are computed from).
    model_points : array_like, shape (m, 2)
        The model's samples (the same model for every detection).
    image_shapes : mapping
        ``(H, W)`` of every image key.
    histograms : array_like, shape (N, B)
        Each detection's interior colour histogram
        (:func:`~shapetree.detection.interior_histogram`).
    params : DetectParams
        ``collection_rescore``, ``appearance_check``, ``appearance_reference`` and
        ``context_check`` are used.

    Returns
    -------
    collection_score : ndarray, shape (N,)
    table : dict of ndarray, shape (N,)
        ``appearance`` and, with the re-scorer, every term of :func:`rescore_collection`.
    """
    from ._appearance import appearance_agreement

    keys = list(image_keys)
    scores = np.array([float(d["score"]) for d in detections])
    agreement = appearance_agreement(keys, scores, histograms, params.appearance_reference)
    if not params.collection_rescore:
        return scores + params.appearance_check * agreement, {"appearance": agreement}
    rows = [
        detection_terms(
            model_points, d["image_points"], _match_box(d), d["coverage"], image_shapes[k]
        )
        for k, d in zip(keys, detections, strict=True)
    ]
    terms = {t: np.array([r[t] for r in rows]) for t in DETECTION_TERMS}
    for t in RECORD_TERMS:
        try:
            terms[t] = np.array([float(d[t]) for d in detections])
        except KeyError:
            raise ShapeTreeError(
                f"collection_table: a detection record has no {t!r} (made by a shapetree "
                "release before the template check); detect again, or pass "
                "collection_rescore=False"
            ) from None
    terms["appearance"] = agreement
    return rescore_collection(keys, scores, terms, params.context_check)


def _match_box(d: Mapping[str, Any]) -> Sequence[float]:
    """The box of a detection record's match (``match_bbox`` where ``box_refine`` replaced
    its ``bbox``): the box every term is computed from."""
    box = d.get("match_bbox")
    return d["bbox"] if box is None else box


def collection_formula(params: DetectParams) -> str:
    """What the collection score of ``params`` is, in one line (for notes and the CLI)."""
    if params.collection_rescore:
        return (
            "the re-scorer (shapetree.detection.rescore_collection): base score plus fixed "
            "weights of context, outline_dif, frame, coverage, margin, lead, appearance and "
            "the upright template check (template, template_support, template_gain, "
            "box_density), fitted on the ETHZ Pb detections (a logistic fit across photos "
            "plus a conditional-logit fit within each photo)"
        )
    return "score + appearance_check * appearance"
