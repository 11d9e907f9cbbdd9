"""Peers on Kimia-99, same data, same run: rank rows and time per pair beside shapetree.

Peers (optional extras, ``pip install .[peers]``; each is skipped when not importable):

* ``hu``: OpenCV ``cv2.matchShapes`` (Hu-moment invariants, ``CONTOURS_MATCH_I1``);
* ``shape_context``: OpenCV-contrib ``createShapeContextDistanceExtractor``;
* ``fdasrsf``: elastic (SRVF) closed-curve shape distance,
  ``fdasrsf.curve_functions.elastic_distance_curve(..., closed=1)``.

Every method gets the same curves (``shapetree.datasets.load("kimia99")``: outer boundaries,
counter-clockwise), resampled to its own number of points, and the full 99 x 99 matrix
(row = query). Rows are computed in ``--workers`` processes and cached under
``--cache-dir`` (one ``.npy`` per finished row), so a killed run resumes.

Run::

    SHAPETREE_DATA=../shared/datasets python benchmarks/peers.py \\
        --json benchmarks/results/peers_kimia99.json
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import time
from collections.abc import Callable
from multiprocessing import get_context
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, machine, write_json  # noqa: E402

from shapetree import datasets  # noqa: E402
from shapetree._atomic import atomic_open  # noqa: E402
from shapetree._bench import PAPER_TABLES  # noqa: E402
from shapetree._cache import cache_root  # noqa: E402
from shapetree.curves import resample  # noqa: E402
from shapetree.retrieval import evaluate, kimia_ranks  # noqa: E402

PEERS = ("hu", "shape_context", "fdasrsf")


def _hu(a: np.ndarray, b: np.ndarray) -> float:
    import cv2

    return float(cv2.matchShapes(a, b, cv2.CONTOURS_MATCH_I1, 0.0))


_SC = None


def _shape_context(a: np.ndarray, b: np.ndarray) -> float:
    import cv2

    global _SC
    if _SC is None:
        _SC = cv2.createShapeContextDistanceExtractor()
    return float(_SC.computeDistance(a, b))


def _fdasrsf(a: np.ndarray, b: np.ndarray) -> float:
    from fdasrsf.curve_functions import elastic_distance_curve

    return float(elastic_distance_curve(a, b, closed=1)[0])


def _available(peer: str) -> str | None:
    """``None`` when usable, else why not."""
    try:
        if peer in ("hu", "shape_context"):
            import cv2

            if peer == "shape_context" and not hasattr(cv2, "createShapeContextDistanceExtractor"):
                return "cv2 has no createShapeContextDistanceExtractor (needs opencv-contrib)"
        else:
            import fdasrsf.curve_functions  # noqa: F401
    except ImportError as exc:
        return f"not importable: {exc}"
    return None


def _prep(peer: str, curve: np.ndarray, n: int) -> np.ndarray:
    c = resample(curve, n, closed=True)
    if peer in ("hu", "shape_context"):
        return np.ascontiguousarray(c, dtype=np.float32).reshape(-1, 1, 2)
    return np.ascontiguousarray(c.T)  # fdasrsf: (2, N)


_FUNCS: dict[str, Callable[[np.ndarray, np.ndarray], float]] = {
    "hu": _hu,
    "shape_context": _shape_context,
    "fdasrsf": _fdasrsf,
}
_STATE: dict = {}


def _init(peer: str, curves: list[np.ndarray]) -> None:
    _STATE["peer"], _STATE["curves"] = peer, curves


def _row(i: int) -> tuple[int, np.ndarray]:
    f, cs = _FUNCS[_STATE["peer"]], _STATE["curves"]
    return i, np.array([0.0 if i == j else f(cs[i], cs[j]) for j in range(len(cs))])


def peer_matrix(
    peer: str, curves: list[np.ndarray], n: int, workers: int, cache: Path | None
) -> tuple[np.ndarray, float, int]:
    """Full matrix of one peer; returns (D, seconds, pairs computed now)."""
    cs = [_prep(peer, c, n) for c in curves]
    h = hashlib.sha256(f"{peer}:{n}".encode())
    for c in cs:
        h.update(c.tobytes())
    folder = None if cache is None else cache / f"{peer}_{h.hexdigest()[:16]}"
    N = len(cs)
    D = np.full((N, N), np.nan)
    todo = []
    for i in range(N):
        p = None if folder is None else folder / f"row_{i:04d}.npy"
        if p is not None and p.is_file():
            try:
                r = np.load(p)
                if r.shape == (N,) and np.isfinite(r).all():
                    D[i] = r
                    continue
            except (OSError, ValueError):
                pass
        todo.append(i)
    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    from tqdm.auto import tqdm

    with get_context("fork").Pool(workers, initializer=_init, initargs=(peer, cs)) as pool:
        for i, r in tqdm(pool.imap_unordered(_row, todo), total=len(todo), desc=peer):
            D[i] = r
            if folder is not None:
                with atomic_open(folder / f"row_{i:04d}.npy") as fh:
                    np.save(fh, r)
    return D, time.perf_counter() - t0, len(todo) * (N - 1)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument(
        "--preset",
        default="kimia99",
        help="matcher preset of the shapetree row (kimia99: tuned on this set, as committed; "
        "general: the untuned default)",
    )
    ap.add_argument(
        "--peers", default=",".join(PEERS), help="comma-separated subset of " + ",".join(PEERS)
    )
    ap.add_argument("--hu-points", type=int, default=100)
    ap.add_argument("--sc-points", type=int, default=100)
    ap.add_argument("--fdasrsf-points", type=int, default=40)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--cache-dir", default=str(cache_root() / "peers"))
    ap.add_argument("--no-shapetree", action="store_true", help="skip the shapetree row")
    ap.add_argument("--json", default=str(RESULTS / "peers_kimia99.json"))
    args = ap.parse_args(argv)

    ds = datasets.load("kimia99", n_points=200, progress=False)
    labels = np.asarray(ds.labels)
    N = len(labels)
    cache = Path(args.cache_dir) if args.cache_dir else None
    points = {"hu": args.hu_points, "shape_context": args.sc_points, "fdasrsf": args.fdasrsf_points}
    rows: dict[str, dict] = {}
    if not args.no_shapetree:
        # exactly `shapetree evaluate kimia99 --preset PRESET`, timed here
        t0 = time.perf_counter()
        rec = evaluate("kimia99", args.preset, progress=True, verbose=False, workers=args.workers)
        dt = time.perf_counter() - t0
        r = np.asarray(rec["ranks"])
        rows["shapetree"] = {
            "ranks": [int(x) for x in r],
            "sum": int(r.sum()),
            "seconds": round(dt, 2),
            "preset": args.preset,
            "seconds_matrix": rec["seconds_matrix"],
            "ms_per_pair_wall": round(1e3 * dt / (N * N), 4),
            "params": rec["params"],
            "workers": args.workers,
        }
    for peer in [s.strip() for s in args.peers.split(",") if s.strip()]:
        if peer not in PEERS:
            ap.error(f"unknown peer {peer!r}")
        why = _available(peer)
        if why is not None:
            print(f"skipping {peer}: {why}")
            rows[peer] = {"skipped": why}
            continue
        D, dt, computed = peer_matrix(peer, ds.curves, points[peer], args.workers, cache)
        r = kimia_ranks(D, labels)
        rows[peer] = {
            "ranks": [int(x) for x in r],
            "sum": int(r.sum()),
            "n_points": points[peer],
            "seconds": round(dt, 2),
            "pairs_computed": computed,
            "ms_per_pair_wall": round(1e3 * dt / computed, 4) if computed else None,
            "workers": args.workers,
        }
    width = 26
    print("Kimia-99: same-class shapes at ranks 1..10 (99 queries), time per pair (wall)")
    print("Method".ljust(width) + " ".join(f"{k:>3}" for k in range(1, 11)) + "  sum  ms/pair")
    for m, v in list(rows.items()) + [
        (n, {"ranks": r}) for n, r in PAPER_TABLES["kimia99"]["rows"]
    ]:
        if "ranks" not in v:
            print(m.ljust(width) + f"skipped ({v['skipped']})")
            continue
        t = v.get("ms_per_pair_wall")
        ts = f"{t:8.3f}" if t is not None else ("   (paper)" if "seconds" not in v else "  cached")
        print(
            m.ljust(width)
            + " ".join(f"{x:>3d}" for x in v["ranks"])
            + f" {sum(v['ranks']):4d} {ts}"
        )
    write_json(
        Path(args.json),
        {
            "dataset": "kimia99",
            "command": "python "
            + " ".join([sys.argv[0], *(argv if argv is not None else sys.argv[1:])]),
            "methods": rows,
            "paper_table": PAPER_TABLES["kimia99"]["rows"],
            "machine": machine(),
            "note": "time per pair = wall seconds / pairs computed, with --workers processes "
            "(shapetree: threads); the machine is shared, so timings include contention",
        },
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
