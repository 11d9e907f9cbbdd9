"""Small synthetic curves shared by the tests (made in code, no data files)."""

from __future__ import annotations

import numpy as np


def blob(n: int, rng: np.random.Generator, *, wobble: float = 0.25, closed: bool = True):
    """A random star-shaped closed curve (or an open arc) with ``n`` points, counter-clockwise."""
    if closed:
        t = np.sort(rng.uniform(0, 2 * np.pi, n))
        t += np.linspace(0, 2 * np.pi, n, endpoint=False) - t  # keep them spread out
        t += rng.uniform(-0.3, 0.3, n) * (2 * np.pi / n)
    else:
        t = np.linspace(0, 1.5 * np.pi, n) + rng.uniform(-0.2, 0.2, n) * (1.5 * np.pi / n)
    r = 1 + wobble * rng.normal(size=n)
    r = np.clip(r, 0.3, None)
    return np.c_[r * np.cos(t), r * np.sin(t)]


def similarity(p: np.ndarray, angle: float, scale: float, shift) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return scale * p @ np.array([[c, -s], [s, c]]).T + np.asarray(shift, float)
