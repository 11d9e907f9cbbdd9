"""ETHZ: a second model for the choice *inside* each image.

``ethz_misses.py`` shows that most held-out misses of mugs (14 of 22 under the 20% rule)
and a third of the giraffes' are found by one of the image's kept detections that ranks
below another detection *of the same image*, which is then a false positive. The collection
re-scorer is fitted to tell true from false detections across all images at once; the
choice among the detections of one image is a different question (which of these five
places is the object, given that the photo holds one?). This script fits a model for that
question alone and combines it with the shipped ranking. Protocol, written before any of
its scores were seen:

- rows: the twelve shipped terms of every kept detection, from ``ethz_template.py --rows``;
  label IoU >= 0.2 with a ground-truth box;
- the *global* score of each row: the shipped re-scorer held out, exactly as the headline
  (``set_chosen_in_each_fold`` of ``ethz_template.py``: term set and L2 chosen inside the
  fold on the four training classes, fitted on them);
- the *within* model: a conditional logit over each image's detections of one model (a
  softmax over the image's kept detections; the likelihood is the probability mass on its
  true ones), on the twelve terms standardised on the training rows, fitted on the
  training classes' images that hold a true detection and at least two detections, with an
  L2 penalty from ``L2_GRID``; it has no intercept, and the image-level terms (``lead``,
  ``appearance`` of the reference set, the frame of the image) cancel only where equal;
- combinations of the two:

  * ``global``: the shipped ranking alone;
  * ``permute``: each image keeps its own set of global scores, handed to its detections
    in the within model's order (the image's best global score goes to the detection the
    within model likes best): the within model decides the order inside each image, the
    global one how images compare;
  * ``sum_g`` for g in 0.25, 0.5, 1, 2: global + g * the within score, both in units of
    their standard deviation over the training rows;

- the combination and the within model's L2 are chosen inside each fold by an inner
  leave-one-class-out over the four training classes (the global part of each inner fold:
  the outer fold's chosen term set and L2, fitted on the three other training classes),
  ties to the earlier combination and then the larger penalty; fitted on the four classes
  and scored on the fifth: ``chosen_in_each_fold``, the headline. Each combination with
  only the L2 chosen inside each fold is reported beside it.

Added on 2026-12-07, after the held-out scores on the ``score_pool`` 30 detections were
seen (the combination chosen in each fold beat the shipped ranking there): ``fit_all``, the
constants to ship. The term set and its L2 are chosen on all five classes (``best_set``),
the combination and the within model's L2 by leave-one-class-out over all five (the same
rule and ties as inside each fold), then both models are fitted on all five classes. A
``sum_g`` combination is one linear form in the twelve terms: ``fit_all`` gives its weight
per unit of each term with ``base`` = 1 (``RESCORER_WEIGHTS``' units) and checks that the
form ranks the rows as the combination does.

``--score-rows`` (added the same day, for issue 14's item 2): the rows of a run on
another edge source (the own edge map), each of its classes scored by the combination
chosen inside the fold and fitted on the four training classes of ``--rows``: held out as
to class and edge source (``cross_to_other_edges``).

``--relations`` (added on 2026-12-07, session 46, after the within model was adopted and
before any score with it was seen). The held-out misses of the adopted ranking (scratch
diagnosis with ``ethz_misses.diagnose``) are giraffes lost inside their own image to a
detection of a part of the animal (the true box holds the best one) and mugs lost as the
second or later mug of a photo that holds several (14 of the 18 missed mugs,
``ethz_misses.py --within``; 13 when this was declared, a miscount). The twelve terms
describe each detection alone, or its base against the image's best (``margin``,
``lead``); none says how its box sits among the other boxes its image keeps. With
``--relations`` the within model sees three more terms, from the kept boxes of the same
model in the same image (no label): ``contains``, the largest share of another kept box
that lies inside this one; ``inside``, the largest share of this box that lies inside
another kept box; ``log_area_ratio``, the log of this box's area over the largest kept box
of the image (0 for an image's only detection). The global fit, the combinations, the
penalties and every choice are as above. Adoption rule, fixed before the run: adopt if the
combination chosen in each fold scores higher held out under the 20% rule than without
them (0.8886) and not lower under PASCAL (0.8224).

``--pool-rows`` (added on 2026-12-07, session 46, after ``--relations`` was scored and
before any score with it was seen): the rows of the same detector run on another edge
source (the own edge map) join the training rows of every fit, global and within, inner
and outer, as rows of their class (each image's detections of one source form their own
group); every DR is still scored on ``--rows``' detections alone, and a class left out is
left out of both sources. The same detections seen through a second edge map are more
examples of what a right and a wrong place look like, from the same four classes.
Adoption rule, fixed before the run: adopt if the combination chosen in each fold scores
higher held out under the 20% rule than without the pooled rows (0.8886), not lower under
PASCAL (0.8224), and the own run's held-out figure (``--score-rows``) not lower (0.8498).

Mean DR at 0.4 FPPI under the 20% rule and under PASCAL's 50%. Usage::

    python3 benchmarks/ethz_within_image.py --rows ROWS_OF_ethz_template.py [--score-rows OWN_ROWS]

Writes ``benchmarks/results/ethz_within_image_pb.json`` (or ``--json``).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

sys.path.insert(0, str(Path(__file__).resolve().parent))

import ethz_verify as V  # noqa: E402
from _ethz_rows import RESCORER_TERMS, Rows, finish, held_line, held_record, parser  # noqa: E402
from ethz_collection_terms import SHIPPED  # noqa: E402
from ethz_template import CANDIDATES, best_set  # noqa: E402

from shapetree.detection._ethz_eval import ETHZ_CLASSES, ethz_root  # noqa: E402

#: the box relations of ``--relations`` (see the protocol)
RELATION_TERMS = ("contains", "inside", "log_area_ratio")
COMBINATIONS = ("global", "permute", "sum_0.25", "sum_0.5", "sum_1", "sum_2")
#: each combination's place in COMBINATIONS (ties go to the earlier)
ORDER = {cb: i for i, cb in enumerate(COMBINATIONS)}


class PooledScorer(V._Scorer):
    """A scorer over the rows of two runs whose DR counts the first run's rows only."""

    def __init__(self, root, rows: list[dict], n_images: int, n_first: int) -> None:
        super().__init__(root, rows, n_images)
        self.first = np.arange(len(rows)) < n_first

    def rows_of(self, cls: str) -> np.ndarray:
        return np.flatnonzero((self.cls == cls) & self.first)


def pooled_rows(r: Rows, path: str, data) -> tuple[Rows, np.ndarray]:
    """``r`` with the rows of ``path`` appended (a :class:`PooledScorer`), and the group
    keys (the second run's keys prefixed, so each source's detections are their own group)."""
    extra = json.loads(Path(path).read_text())
    rows = r.rows + extra
    sc = PooledScorer(ethz_root(data), rows, r.sc.n, len(r.rows))
    keys = np.array([row["key"] for row in r.rows] + ["pool:" + row["key"] for row in extra])
    return Rows(rows, sc, sc.col("iou") >= 0.2, r.t0), keys


def relation_terms(rows: list[dict], cls: np.ndarray) -> np.ndarray:
    """``RELATION_TERMS`` of every row, from the boxes of its (model, image) group."""
    box = np.array([r["bbox"] for r in rows], float)
    area = np.maximum((box[:, 2] - box[:, 0]) * (box[:, 3] - box[:, 1]), 1e-9)
    out = np.zeros((len(rows), 3))
    group = groups_of(np.array([r["key"] for r in rows]), cls)
    for g in np.unique(group):
        idx = np.flatnonzero(group == g)
        b = box[idx]
        iw = np.clip(
            np.minimum(b[:, None, 2], b[None, :, 2]) - np.maximum(b[:, None, 0], b[None, :, 0]),
            0,
            None,
        )
        ih = np.clip(
            np.minimum(b[:, None, 3], b[None, :, 3]) - np.maximum(b[:, None, 1], b[None, :, 1]),
            0,
            None,
        )
        inter = iw * ih
        np.fill_diagonal(inter, 0.0)
        a = area[idx]
        out[idx, 0] = (inter / a[None, :]).max(1)  # share of another box inside this one
        out[idx, 1] = (inter / a[:, None]).max(1)  # share of this box inside another
        out[idx, 2] = np.log(a / a.max())
    return out


def groups_of(keys: np.ndarray, cls: np.ndarray) -> np.ndarray:
    """An integer id per (model, image): the rows one image keeps for one model."""
    ids: dict = {}
    return np.array([ids.setdefault(g, len(ids)) for g in zip(cls, keys)])


def fit_within(x: np.ndarray, label: np.ndarray, group: np.ndarray, tr: np.ndarray, l2: float):
    """Conditional logit weights (on ``x`` standardised over ``tr``) and that scaling."""
    mu, sd = x[tr].mean(0), x[tr].std(0) + 1e-12
    keep = np.zeros(len(label), bool)
    for g in np.unique(group[tr]):
        r = tr & (group == g)
        if r.sum() >= 2 and label[r].any():
            keep |= r
    z, y, gid = (x[keep] - mu) / sd, label[keep].astype(float), group[keep]
    _, gi = np.unique(gid, return_inverse=True)
    n_g = gi.max() + 1

    def f(w: np.ndarray) -> tuple[float, np.ndarray]:
        s = z @ w
        m = np.full(n_g, -np.inf)
        np.maximum.at(m, gi, s)
        e = np.exp(s - m[gi])
        tot = np.bincount(gi, e, n_g)
        pos = np.bincount(gi, e * y, n_g)
        loss = -(np.log(pos) - np.log(tot)).sum() + l2 * w @ w
        p, q = e / tot[gi], e * y / pos[gi]
        return float(loss), z.T @ (p - q) + 2 * l2 * w

    w = minimize(f, np.zeros(z.shape[1]), jac=True, method="L-BFGS-B").x
    return w, mu, sd


def combine(name: str, g: np.ndarray, w: np.ndarray, group: np.ndarray, tr: np.ndarray):
    """The combined score of every row (``g`` global, ``w`` within score)."""
    if name == "global":
        return g
    if name == "permute":
        out = np.empty_like(g)
        order = np.argsort(group, kind="stable")
        bounds = np.flatnonzero(np.diff(group[order])) + 1
        for idx in np.split(order, bounds):
            out[idx[np.argsort(-w[idx], kind="stable")]] = np.sort(g[idx])[::-1]
        return out
    gamma = float(name.split("_", 1)[1])
    return g / g[tr].std() + gamma * w / (w[tr].std() + 1e-12)


def fit_global(x_set: np.ndarray, label: np.ndarray, tr: np.ndarray, l2: float):
    """The global logistic fit on the rows ``tr``: ``(mu, sd, w)``, ``w`` without the
    intercept, on the terms standardised over ``tr``."""
    mu, sd = x_set[tr].mean(0), x_set[tr].std(0) + 1e-12
    return mu, sd, V._logistic((x_set[tr] - mu) / sd, label[tr].astype(float), l2)[:-1]


def fit_record(terms, mu, sd, w, x_part: np.ndarray) -> dict:
    """A fit as recorded: its terms, standardisation, weights and the standard deviation
    of its score over the rows ``x_part`` (what a ``sum_g`` combination divides by)."""
    return {
        "terms": list(terms),
        "mean": mu.tolist(),
        "std": sd.tolist(),
        "weights": w.tolist(),
        "score_std": float((((x_part - mu) / sd) @ w).std()),
    }


def linear_form(global_fit: dict, within_fit: dict, gamma: float) -> dict[str, float]:
    """The ``sum_gamma`` combination of two recorded fits (:func:`fit_record`) as one
    weight per unit of each term, ``base`` = 1."""
    coef: dict[str, float] = {}
    for f, scale in ((global_fit, 1.0), (within_fit, gamma)):
        for t, w, sd in zip(f["terms"], f["weights"], f["std"], strict=True):
            coef[t] = coef.get(t, 0.0) + scale * w / sd / f["score_std"]
    b = coef.pop("base")
    if b <= 0:
        raise ValueError(f"the combined form weighs base {b:.4g} <= 0")
    return {t: c / b for t, c in coef.items()}


def choose_combination(sc, fold_scores, combos, set_name, set_l2, classes, tr) -> tuple:
    """The combination and within L2 with the best leave-one-class-out mean over
    ``classes`` (each fitted on ``tr`` less the class; ties to the earlier combination,
    then the larger L2): ``(best, {combination: inner mean})``."""
    inner_dr: dict = {k: [] for k in combos}
    for c in classes:
        fs = fold_scores(set_name, set_l2, tr & (sc.cls != c))
        for k in combos:
            inner_dr[k].append(sc.dr(c, fs[k])[0])
    inner_mean = {k: float(np.mean(v)) for k, v in inner_dr.items()}
    best = max(combos, key=lambda k: (inner_mean[k], -ORDER[k[0]], k[1] or 0.0))
    return best, inner_mean


def fit_all_within(sc, label, x, x_of, group, fold_scores, combos, terms) -> dict:
    """The term set, the combination and the within L2 chosen on all five classes, both
    models fitted on all five: the constants to ship, with their in-sample DR."""
    classes = list(ETHZ_CLASSES)
    rows = np.ones(len(label), bool)
    set_name, set_l2, _ = best_set(sc, label, x_of, classes)
    best, inner_mean = choose_combination(sc, fold_scores, combos, set_name, set_l2, classes, rows)
    out = {
        "set": set_name,
        "set_l2": set_l2,
        "combination": best[0],
        "within_l2": best[1],
        "inner_mean": round(inner_mean[best], 4),
        "inner_means": {f"{k[0]} l2={k[1]}": round(v, 4) for k, v in inner_mean.items()},
    }
    fs = fold_scores(set_name, set_l2, rows)
    ins = {c: sc.dr(c, fs[best]) for c in classes}
    out["in_sample_overlap_20"] = V._with_mean(ins, 0)
    out["in_sample_overlap_50"] = V._with_mean(ins, 1)
    if not best[0].startswith("sum_"):
        return out
    set_terms = tuple(SHIPPED) + tuple(CANDIDATES[set_name])
    xg = x_of[set_name]
    w_w, mu_w, sd_w = fit_within(x, label, group, rows, best[1])
    out["global_fit"] = fit_record(set_terms, *fit_global(xg, label, rows, set_l2), xg)
    out["within_fit"] = fit_record(terms, mu_w, sd_w, w_w, x)
    out["gamma"] = gamma = float(best[0].split("_", 1)[1])
    form = linear_form(out["global_fit"], out["within_fit"], gamma)
    lin = x[:, terms.index("base")] + sum(w * x[:, terms.index(t)] for t, w in form.items())
    ins_lin = {c: sc.dr(c, lin) for c in classes}
    out["weights_base_1"] = {t: round(w, 4) for t, w in form.items()}
    out["linear_form_in_sample_overlap_20"] = V._with_mean(ins_lin, 0)
    out["linear_form_in_sample_overlap_50"] = V._with_mean(ins_lin, 1)
    return out


def transfer(x_set, x, label, group, tr, set_l2: float, combination, within_l2):
    """Both models fitted on the rows ``tr`` (the global one on ``x_set``); returns a
    function scoring another run's ``(x_set, x, group)`` by ``combination``, each score
    in units of its standard deviation over ``tr``."""
    mu_g, sd_g, w_g = fit_global(x_set, label, tr, set_l2)
    g_tr = ((x_set[tr] - mu_g) / sd_g) @ w_g
    if combination == "global":
        return lambda xs, _x, _grp: ((xs - mu_g) / sd_g) @ w_g
    w_w, mu_w, sd_w = fit_within(x, label, group, tr, within_l2)
    ws_tr = ((x[tr] - mu_w) / sd_w) @ w_w

    def score(xs, xt, grp):
        g, ws = ((xs - mu_g) / sd_g) @ w_g, ((xt - mu_w) / sd_w) @ w_w
        if combination == "permute":
            return combine("permute", g, ws, grp, np.ones(len(g), bool))
        gamma = float(combination.split("_", 1)[1])
        return g / g_tr.std() + gamma * ws / (ws_tr.std() + 1e-12)

    return score


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument(
        "--score-rows",
        default=None,
        help="rows of a run on another edge source: score each of its classes by the "
        "combination chosen and fitted on --rows' four other classes",
    )
    ap.add_argument(
        "--relations",
        action="store_true",
        help="the within model also sees RELATION_TERMS (the boxes' relations in the image)",
    )
    ap.add_argument(
        "--pool-rows",
        default=None,
        help="rows of the same detector on another edge source: they join every fit's "
        "training rows (DR still scored on --rows alone)",
    )
    args = ap.parse_args()
    r = Rows.read(args.rows, args.data)
    group_keys = np.array([row["key"] for row in r.rows])
    if args.pool_rows:
        if args.relations:
            raise SystemExit("--pool-rows and --relations are separate experiments")
        r, group_keys = pooled_rows(r, args.pool_rows, args.data)
    sc, label = r.sc, r.label
    terms = list(RESCORER_TERMS) + (list(RELATION_TERMS) if args.relations else [])
    x = r.matrix()
    if args.relations:
        x = np.c_[x, relation_terms(r.rows, sc.cls)]
    group = groups_of(group_keys, sc.cls)
    x_of = r.candidates()
    classes = list(ETHZ_CLASSES)
    combos = [("global", None)] + [(c, l2) for c in COMBINATIONS[1:] for l2 in V.L2_GRID]

    def fold_scores(set_name, set_l2, tr) -> dict:
        """Every combination's scores (``{(combination, l2): scores}``) fitted on ``tr``."""
        g = V._fit_score(x_of[set_name], label, tr, set_l2)
        out = {("global", None): g}
        for l2 in V.L2_GRID:
            w, mu, sd = fit_within(x, label, group, tr, l2)
            ws = ((x - mu) / sd) @ w
            for cb in COMBINATIONS[1:]:
                out[(cb, l2)] = combine(cb, g, ws, group, tr)
        return out

    outer: dict = {}
    fixed: dict = {c: {} for c in COMBINATIONS}
    held: dict = {}
    for c_out in classes:
        inner = [c for c in classes if c != c_out]
        set_name, set_l2, _ = best_set(sc, label, x_of, inner)
        best, inner_mean = choose_combination(
            sc, fold_scores, combos, set_name, set_l2, inner, sc.cls != c_out
        )
        fs = fold_scores(set_name, set_l2, sc.cls != c_out)
        held[c_out] = sc.dr(c_out, fs[best])
        outer[c_out] = {
            "set": set_name,
            "set_l2": set_l2,
            "combination": best[0],
            "within_l2": best[1],
            "inner_mean": round(inner_mean[best], 4),
        }
        for cb in COMBINATIONS:  # each combination alone, its L2 chosen inside the fold
            k = max((k for k in combos if k[0] == cb), key=lambda k: (inner_mean[k], k[1] or 0.0))
            fixed[cb][c_out] = sc.dr(c_out, fs[k])
        print(f"{c_out}: {outer[c_out]} -> {held[c_out]}", flush=True)
    out: dict = {"protocol": __doc__, "terms": terms, "combinations": {}}
    if args.score_rows:
        te = Rows.read(args.score_rows, args.data)
        x_te, x_te_of = te.matrix(), te.candidates()
        if args.relations:
            x_te = np.c_[x_te, relation_terms(te.rows, te.sc.cls)]
        g_te = groups_of(np.array([row["key"] for row in te.rows]), te.sc.cls)
        cross = {}
        for c_out in classes:
            ch = outer[c_out]
            f = transfer(
                x_of[ch["set"]],
                x,
                label,
                group,
                sc.cls != c_out,
                ch["set_l2"],
                ch["combination"],
                ch["within_l2"],
            )
            cross[c_out] = te.sc.dr(c_out, f(x_te_of[ch["set"]], x_te, g_te))
        out["cross_to_other_edges"] = cx = {"score_rows": args.score_rows}
        cx |= held_record(cross)
        print(held_line(f"{args.score_rows} held out:", cx))
    for cb in COMBINATIONS:
        out["combinations"][cb] = held_record(fixed[cb])
        print(held_line(f"{cb:9s}", out["combinations"][cb]))
    out["chosen_in_each_fold"] = ch = held_record(held, outer)
    print(held_line("combination chosen in each fold:", ch))
    out["fit_all"] = fa = fit_all_within(sc, label, x, x_of, group, fold_scores, combos, terms)
    print(
        f"fit_all: {fa['set']} (L2 {fa['set_l2']}), {fa['combination']} "
        f"(within L2 {fa['within_l2']}), in sample {fa['in_sample_overlap_20']['mean']:.4f} / "
        f"{fa['in_sample_overlap_50']['mean']:.4f}"
    )
    if "weights_base_1" in fa:
        print(f"  as one linear form: {fa['weights_base_1']}")
        print(
            f"  its in-sample DR {fa['linear_form_in_sample_overlap_20']['mean']:.4f} / "
            f"{fa['linear_form_in_sample_overlap_50']['mean']:.4f}"
        )
    finish(out, args, r.t0, "ethz_within_image.py", "ethz_within_image_pb.json")


if __name__ == "__main__":
    main()
