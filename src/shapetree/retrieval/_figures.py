"""Pictures of retrieval results (matplotlib, Agg; imported lazily)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from shapetree.plotting import save_figure
from shapetree.retrieval._protocols import ranked_neighbours

__all__ = ["plot_bullseye_per_class", "plot_retrieval_grid", "plot_search"]


def _draw(ax, curve: np.ndarray, colour: str) -> None:
    c = np.asarray(curve, dtype=float)
    c = np.vstack([c, c[:1]])
    ax.fill(c[:, 0], c[:, 1], color=colour, alpha=0.25, lw=0)
    ax.plot(c[:, 0], c[:, 1], color=colour, lw=1.2)
    ax.set_aspect("equal")
    ax.invert_yaxis()  # image coordinates: y points down
    ax.set_xticks([])
    ax.set_yticks([])


def plot_retrieval_grid(
    D: ArrayLike,
    labels: ArrayLike,
    curves: Sequence[ArrayLike],
    path: str | os.PathLike[str],
    *,
    queries: Sequence[int] | None = None,
    n_top: int = 10,
    title: str = "",
) -> Path:
    """Queries (first column) with their nearest shapes; wrong-class matches in red.

    Parameters
    ----------
    D : array_like, shape (n, n)
        Distance matrix (row = query).
    labels : array_like, shape (n,)
    curves : sequence of array_like, each shape (k, 2)
    path : path-like
        Output image (PNG, ...).
    queries : sequence of int, optional
        Rows to show; default one query per class (the one with most wrong matches).
    n_top : int
        Matches shown per query (the query itself excluded).
    title : str

    Returns
    -------
    pathlib.Path
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    lab = np.asarray(labels)
    order = ranked_neighbours(D, exclude_self=True)[:, :n_top]
    wrong = (lab[order] != lab[:, None]).sum(axis=1)
    if queries is None:
        queries = []
        for c in sorted(set(lab.tolist())):
            idx = np.flatnonzero(lab == c)
            queries.append(int(idx[np.argmax(wrong[idx])]))
        queries = queries[:12]
    nq = len(queries)
    fig, axes = plt.subplots(nq, n_top + 1, figsize=(1.1 * (n_top + 1), 1.15 * nq), squeeze=False)
    for r, q in enumerate(queries):
        _draw(axes[r, 0], curves[q], "black")
        axes[r, 0].set_ylabel(str(lab[q])[:12], fontsize=7)
        for k in range(n_top):
            j = order[q, k]
            ok = lab[j] == lab[q]
            ax = axes[r, k + 1]
            _draw(ax, curves[j], "tab:blue" if ok else "red")
            if not ok:
                for s in ax.spines.values():
                    s.set_color("red")
                    s.set_linewidth(2)
            if r == 0:
                ax.set_title(str(k + 1), fontsize=8)
    axes[0, 0].set_title("query", fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, out, dpi=90)
    plt.close(fig)
    return out


def plot_bullseye_per_class(
    per_class: dict[str, float],
    path: str | os.PathLike[str],
    *,
    overall: float | None = None,
    title: str = "Bull's-eye per class",
    second: dict[str, float] | None = None,
    labels: tuple[str, str] = ("pairwise", "re-ranked"),
    second_overall: float | None = None,
) -> Path:
    """Horizontal bar chart of per-class bull's-eye scores (sorted, worst at the bottom).

    Parameters
    ----------
    per_class : dict
        ``{class: percentage}`` from :func:`shapetree.retrieval.bullseye_per_class`.
    path : path-like
    overall : float, optional
        Drawn as a vertical line.
    title : str
    second : dict, optional
        A second score per class (e.g. after re-ranking), drawn as dots on the bars.
    labels : (str, str)
        Legend names of ``per_class`` and ``second``.
    second_overall : float, optional
        Overall value of ``second``, drawn as a dotted line.

    Returns
    -------
    pathlib.Path
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    items = sorted(per_class.items(), key=lambda kv: kv[1])
    names = [k for k, _ in items]
    vals = np.array([v for _, v in items])
    fig, ax = plt.subplots(figsize=(7, max(3.0, 0.16 * len(items) + 1)))
    colours = ["red" if v < 70 else "tab:orange" if v < 90 else "tab:blue" for v in vals]
    ax.barh(np.arange(len(vals)), vals, color=colours, label=labels[0] if second else None)
    if second:
        ax.plot([second[k] for k in names], np.arange(len(vals)), "k.", ms=4, label=labels[1])
    ax.set_yticks(np.arange(len(vals)), names, fontsize=6)
    ax.set_xlim(0, 100)
    ax.set_xlabel("bull's-eye (%)")
    if overall is not None:
        ax.axvline(overall, color="black", ls="--", lw=1, label=f"all: {overall:.2f}%")
    if second_overall is not None:
        ax.axvline(
            second_overall,
            color="black",
            ls=":",
            lw=1,
            label=f"all, {labels[1]}: {second_overall:.2f}%",
        )
    if overall is not None or second:
        ax.legend(loc="lower right", fontsize=8)
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, out, dpi=100)
    plt.close(fig)
    return out


def plot_search(
    query: ArrayLike,
    matches: Sequence[ArrayLike],
    captions: Sequence[str],
    path: str | os.PathLike[str],
    *,
    title: str = "",
    per_row: int = 6,
) -> Path:
    """A query outline and its nearest shapes, in rank order, with captions.

    Parameters
    ----------
    query : array_like, shape (n, 2)
        Closed curve in image coordinates (y down).
    matches : sequence of array_like, each shape (k, 2)
        The nearest shapes, best first.
    captions : sequence of str
        One per match (e.g. name and distance).
    path : path-like
        Output picture (written atomically).
    title : str
    per_row : int
        Panels per row (the query takes the first panel).

    Returns
    -------
    pathlib.Path
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    n = len(matches) + 1
    cols = min(per_row, n)
    rows = -(-n // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(1.7 * cols, 1.9 * rows), squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    _draw(axes[0, 0], np.asarray(query), "black")
    axes[0, 0].axis("on")
    axes[0, 0].set_title("query", fontsize=8)
    for i, (curve, cap) in enumerate(zip(matches, captions), start=1):
        ax = axes[i // cols, i % cols]
        _draw(ax, np.asarray(curve), "tab:blue")
        ax.axis("on")
        ax.set_title(f"{i}. {cap}", fontsize=7)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    out = save_figure(fig, path, dpi=100)
    plt.close(fig)
    return out
