"""A prepared shape database: every shape's curves as the matcher samples them, on disk.

:class:`ShapeIndex` holds, for each shape of a collection, its validated outline (as read),
its sampled model curve (:func:`shapetree.matching._api.model_curve`) and its target
samplings, one per phase (:func:`shapetree.matching._api.target_curves`), together with
the shape names, the :class:`~shapetree.matching.MatchConfig` that sampled them, the
package version and :func:`shapetree._cache.code_fingerprint` (its ``"matching"`` scope: the
code a matching cost depends on). The retrieval engine
(:func:`shapetree.retrieval.distance_matrix`, :func:`~shapetree.retrieval.search`) takes it
in place of a list of curves and uses the stored samples as they are, so the distances are
the same numbers as from the curves (and the engine's block cache is shared).

What is stored, and what is not
-------------------------------
Everything that depends on the shape alone is stored: the validated outline, its
smoothing and resampling (the model curve) and the target samplings of every phase; so
a database is read, checked and used without tracing an image or resampling a curve.
Two per-shape precomputations of the matcher are rebuilt on use instead, because storing
them would cost far more than recomputing: the prepared models (shape-trees, Bookstein
and Helmert coordinates of every node, for the plain and mirrored curve: about 1.4 ms per
shape under the ``mpeg7`` preset, once per block of rows, against about 3 s of matching
for that row against 1,400 shapes) and the prepared targets (the Helmert coordinates of
every target triangle, ``O(m^3)``: 3.2 MB per sampling at ``m = 64``, so 9 GB for MPEG-7,
rebuilt in 0.7 ms per block of rows).

A database is only ever used with the configuration, the package version and the code it
was built with: anything else is refused with a :class:`shapetree.ShapeTreeError` that
names what differs and how to rebuild (the outlines are stored, so
``shapetree index build OLD.stidx -o NEW.stidx`` rebuilds one from itself).

File format (version :data:`FORMAT_VERSION`; extension :data:`EXTENSION`)
-------------------------------------------------------------------------
An uncompressed NumPy ``.npz`` (a zip archive of ``.npy`` arrays, read with
``allow_pickle=False``), written atomically (:mod:`shapetree._atomic`, fsynced). Members:

``header``
    ``uint8``: UTF-8 JSON object with ``format`` (``"shapetree-index"``),
    ``format_version``, ``shapetree_version``, ``fingerprint``, ``config``
    (:meth:`MatchConfig.as_dict`), ``n_shapes``, ``phases`` (target samplings per shape),
    ``names`` (list of str), ``created`` (UTC, ISO 8601) and ``arrays``: for each data
    member its ``dtype``, ``shape`` and the SHA-256 of its bytes.
``header_sha256``
    ``uint8``: the hex SHA-256 of ``header``'s bytes, as ASCII.
``outline_xy``, ``outline_offsets``
    The outlines, concatenated (``(N, 2)`` little-endian float64) and the ``n + 1`` start
    offsets (int64): shape ``i`` is ``outline_xy[off[i]:off[i + 1]]``.
``model_xy``, ``model_offsets``
    The model curves, the same way.
``target_xy``, ``target_offsets``
    The target samplings, ``phases`` per shape, shape-major: sampling ``p`` of shape ``i``
    is entry ``i * phases + p`` (``n * phases + 1`` offsets).

Every checksum is verified on load; a damaged, truncated or foreign file raises a
:class:`ShapeTreeError` naming the file.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import os
import struct
import tokenize
import zipfile
import zlib
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from shapetree._errors import ShapeTreeError
from shapetree.curves import as_curve
from shapetree.matching._config import MatchConfig, resolve_config

__all__ = ["EXTENSION", "FORMAT", "FORMAT_VERSION", "ShapeIndex", "is_index_path"]

#: Value of the header's ``format`` entry.
FORMAT = "shapetree-index"
#: Version of the on-disk layout this code writes and reads.
FORMAT_VERSION = 1
#: File extension of a shape database.
EXTENSION = ".stidx"

_DATA = ("outline", "model", "target")
_READ_ERRORS = (
    OSError,
    ValueError,
    KeyError,
    EOFError,
    NotImplementedError,
    zipfile.BadZipFile,
    zlib.error,
    struct.error,
    UnicodeDecodeError,
    SyntaxError,
    tokenize.TokenError,  # numpy's parser of a damaged .npy header (not a ValueError)
)


def is_index_path(spec: str | os.PathLike[str]) -> bool:
    """Whether a path names a shape database (by its extension)."""
    return str(spec).lower().endswith(EXTENSION)


def _current() -> tuple[str, str]:
    import shapetree
    from shapetree._cache import code_fingerprint

    return str(shapetree.__version__), code_fingerprint("matching")


def _pack(arrays: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    off = np.zeros(len(arrays) + 1, dtype="<i8")
    off[1:] = np.cumsum([a.shape[0] for a in arrays])
    xy = np.concatenate(arrays).astype("<f8") if arrays else np.zeros((0, 2), "<f8")
    return np.ascontiguousarray(xy.reshape(-1, 2)), off


def _unpack(xy: np.ndarray, off: np.ndarray) -> list[np.ndarray]:
    return [np.ascontiguousarray(xy[a:b], dtype=np.float64) for a, b in zip(off[:-1], off[1:])]


def _sha(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()


def _config_diff(have: MatchConfig, want: MatchConfig) -> str:
    h, w = have.as_dict(), want.as_dict()
    keys = [k for k in h if h[k] != w.get(k)]
    return ", ".join(f"{k}={h[k]!r} (asked: {w.get(k)!r})" for k in keys)


class ShapeIndex:
    """A prepared collection of closed shapes for retrieval (see the module docstring).

    Build one with :meth:`build`, extend it with :meth:`add`, write it with :meth:`save`
    and read it with :meth:`load`. Pass it to :func:`shapetree.retrieval.search` or
    :func:`shapetree.retrieval.distance_matrix` in place of a list of curves.

    Attributes
    ----------
    config : MatchConfig
        The configuration that sampled the curves (the only one the index is used with).
    names : list of str
        One per shape, unique.
    outlines : list of ndarray, each shape (k_i, 2)
        The validated outlines as given.
    models : list of ndarray
        The model curves (``model_curve(outline, config)``).
    targets : list of list of ndarray
        The target samplings (``target_curves(outline, config)``), one per phase.
    version, fingerprint : str
        Package version and code fingerprint that prepared the curves.
    created : str
        When the index was first built (UTC, ISO 8601).
    """

    def __init__(
        self,
        config: MatchConfig,
        names: list[str],
        outlines: list[np.ndarray],
        models: list[np.ndarray],
        targets: list[list[np.ndarray]],
        *,
        version: str,
        fingerprint: str,
        created: str,
        path: Path | None = None,
    ) -> None:
        self.config = config
        self.names = list(names)
        self.outlines = list(outlines)
        self.models = list(models)
        self.targets = list(targets)
        self.version = version
        self.fingerprint = fingerprint
        self.created = created
        self.path = path

    def __len__(self) -> int:
        return len(self.names)

    def __repr__(self) -> str:
        where = f", path={str(self.path)!r}" if self.path else ""
        return f"ShapeIndex({len(self)} shapes, config: {self.config.describe()}{where})"

    # ------------------------------------------------------------ building

    @classmethod
    def build(
        cls,
        curves: Sequence[ArrayLike],
        names: Sequence[str] | None = None,
        config: MatchConfig | str | None = None,
        *,
        progress: bool = False,
        **options: Any,
    ) -> ShapeIndex:
        """Validate and sample closed curves under a configuration.

        Parameters
        ----------
        curves : sequence of array_like, each shape (k_i, 2)
            Closed curves (arrays, OpenCV contours, shapely polygons).
        names : sequence of str, optional
            Unique names (default ``"shape 0"``, ``"shape 1"``, ...).
        config : MatchConfig, str or None
            Configuration or preset name (default: the ``general`` preset).
        progress : bool
            tqdm progress bar.
        **options
            :class:`MatchConfig` fields changed on top of ``config``.

        Returns
        -------
        ShapeIndex
        """
        cfg = resolve_config(config, **options)
        version, fingerprint = _current()
        created = _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat()
        index = cls(cfg, [], [], [], [], version=version, fingerprint=fingerprint, created=created)
        index.add(curves, names, progress=progress)
        return index

    def add(
        self,
        curves: Sequence[ArrayLike],
        names: Sequence[str] | None = None,
        *,
        progress: bool = False,
    ) -> ShapeIndex:
        """Append shapes (sampled with the index's configuration); returns ``self``.

        Parameters
        ----------
        curves : sequence of array_like
            Closed curves.
        names : sequence of str, optional
            Unique names, none already in the index (default ``"shape N"``).
        progress : bool
            tqdm progress bar.

        Raises
        ------
        ShapeTreeError
            A bad curve (named), a repeated name, or a count mismatch. Nothing is added
            then.
        """
        from shapetree.matching._api import model_curve, target_curves

        self._check_current()
        curves = list(curves)
        if names is None:
            names = [f"shape {len(self) + i}" for i in range(len(curves))]
        names = [str(n) for n in names]
        if len(names) != len(curves):
            raise ShapeTreeError(f"got {len(curves)} curves but {len(names)} names")
        seen = set(self.names)
        for n in names:
            if n in seen:
                raise ShapeTreeError(f"shape name {n!r} is already in the index (names are unique)")
            seen.add(n)
        outlines, models, targets = [], [], []
        if progress:
            from tqdm.auto import tqdm

            it = tqdm(list(zip(curves, names)), desc="preparing", unit="shape")
        else:
            it = zip(curves, names)
        for c, n in it:
            a = as_curve(c, closed=True, name=n)
            outlines.append(np.ascontiguousarray(a, dtype=np.float64))
            models.append(model_curve(a, self.config, closed=True, name=n))
            targets.append(target_curves(a, self.config, closed=True, name=n))
        self.names += names
        self.outlines += outlines
        self.models += models
        self.targets += targets
        return self

    # ------------------------------------------------------------ checks

    def _check_current(self) -> None:
        version, fingerprint = _current()
        if (self.version, self.fingerprint) == (version, fingerprint):
            return
        where = str(self.path) if self.path else "shape index"
        if self.version != version:
            what = f"built by shapetree {self.version}, this is shapetree {version}"
        else:
            what = (
                f"built by other code of shapetree {version} (code fingerprint "
                f"{self.fingerprint[:12]}, this code {fingerprint[:12]})"
            )
        raise ShapeTreeError(
            f"{where}: {what}; its curves may differ from what this version computes, so it "
            f"is not used. Rebuild it (its outlines are kept): shapetree index build "
            f"{where} -o NEW{EXTENSION}"
        )

    def check_config(self, config: MatchConfig) -> None:
        """Refuse a configuration other than the index's (a :class:`ShapeTreeError`)."""
        if config == self.config:
            return
        where = str(self.path) if self.path else "shape index"
        diff = _config_diff(self.config, config)
        raise ShapeTreeError(
            f"{where}: built with another matcher configuration: {diff}. Use the index's own "
            f"configuration (pass config=None / no matching flags), or rebuild it with these "
            f"options: shapetree index build {where} [options] -o NEW{EXTENSION}"
        )

    # ------------------------------------------------------------ file

    def _arrays(self) -> dict[str, np.ndarray]:
        phases = {len(t) for t in self.targets}
        if len(phases) > 1:
            raise ShapeTreeError(f"inconsistent index: {sorted(phases)} target samplings")
        out: dict[str, np.ndarray] = {}
        out["outline_xy"], out["outline_offsets"] = _pack(self.outlines)
        out["model_xy"], out["model_offsets"] = _pack(self.models)
        out["target_xy"], out["target_offsets"] = _pack([b for bs in self.targets for b in bs])
        return out

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the index atomically (a reader never sees a half-written file).

        Parameters
        ----------
        path : path-like
            The file (conventionally ending in :data:`EXTENSION`).

        Returns
        -------
        Path
        """
        from shapetree._atomic import atomic_open

        p = Path(path)
        if p.is_dir():
            raise ShapeTreeError(f"{p}: is a directory, expected a {EXTENSION} file name")
        arrays = self._arrays()
        header = {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "shapetree_version": self.version,
            "fingerprint": self.fingerprint,
            "config": self.config.as_dict(),
            "n_shapes": len(self),
            "phases": len(self.targets[0]) if self.targets else self.config.phases,
            "names": self.names,
            "created": self.created,
            "arrays": {
                k: {"dtype": v.dtype.str, "shape": list(v.shape), "sha256": _sha(v)}
                for k, v in arrays.items()
            },
        }
        hb = np.frombuffer(json.dumps(header, sort_keys=True).encode("utf-8"), dtype=np.uint8)
        hs = np.frombuffer(hashlib.sha256(hb.tobytes()).hexdigest().encode("ascii"), np.uint8)
        with atomic_open(p, "wb", fsync=True) as fh:
            np.savez(fh, header=hb, header_sha256=hs, **arrays)
        self.path = p
        return p

    @classmethod
    def _read(cls, path: str | os.PathLike[str]) -> ShapeIndex:
        """Read and verify a file (checksums, layout) without the compatibility checks."""
        p = Path(path)
        if p.is_dir():
            raise ShapeTreeError(f"{p}: is a directory, not a shape index ({EXTENSION} file)")
        if not p.exists():
            raise ShapeTreeError(f"{p}: no such shape index")

        def bad(why: str) -> ShapeTreeError:
            return ShapeTreeError(
                f"{p}: damaged or not a shape index ({why}); rebuild it with shapetree index build"
            )

        try:
            with open(p, "rb") as fh:
                if fh.read(4) != b"PK\x03\x04":
                    raise bad("not a zip archive")
            with np.load(p, allow_pickle=False) as z:
                members = set(z.files)
                if not {"header", "header_sha256"} <= members:
                    raise bad("no shapetree index header")
                hb = z["header"]
                hs = z["header_sha256"].tobytes().decode("ascii")
                if hb.dtype != np.uint8 or hashlib.sha256(hb.tobytes()).hexdigest() != hs:
                    raise bad("header checksum mismatch")
                header = json.loads(hb.tobytes().decode("utf-8"))
                if header.get("format") != FORMAT:
                    raise bad(f"format {header.get('format')!r}")
                fv = header.get("format_version")
                if fv != FORMAT_VERSION:
                    raise ShapeTreeError(
                        f"{p}: shape index format version {fv}, this shapetree reads version "
                        f"{FORMAT_VERSION}; rebuild it with shapetree index build"
                    )
                arrays = {}
                for k, spec in header["arrays"].items():
                    if k not in members:
                        raise bad(f"member {k} missing")
                    a = z[k]
                    if a.dtype.str != spec["dtype"] or list(a.shape) != spec["shape"]:
                        raise bad(f"member {k} has dtype/shape {a.dtype.str} {list(a.shape)}")
                    if _sha(a) != spec["sha256"]:
                        raise bad(f"checksum mismatch in {k}")
                    arrays[k] = a
        except ShapeTreeError:
            raise
        except _READ_ERRORS as exc:
            raise bad(f"{type(exc).__name__}: {exc}") from None
        try:
            n, phases, names = int(header["n_shapes"]), int(header["phases"]), header["names"]
            outlines = _unpack(arrays["outline_xy"], arrays["outline_offsets"])
            models = _unpack(arrays["model_xy"], arrays["model_offsets"])
            flat = _unpack(arrays["target_xy"], arrays["target_offsets"])
            if not (len(names) == len(outlines) == len(models) == n and len(flat) == n * phases):
                raise ValueError("counts disagree")
            targets = [flat[i * phases : (i + 1) * phases] for i in range(n)]
        except (KeyError, ValueError, TypeError) as exc:
            raise bad(f"inconsistent layout: {exc}") from None
        try:
            config = MatchConfig.from_dict(header["config"])
        except (ShapeTreeError, TypeError) as exc:
            raise ShapeTreeError(
                f"{p}: built with a matcher configuration this shapetree does not know "
                f"({' '.join(str(exc).split())}); rebuild it with shapetree index build"
            ) from None
        return cls(
            config,
            [str(s) for s in names],
            outlines,
            models,
            targets,
            version=str(header["shapetree_version"]),
            fingerprint=str(header["fingerprint"]),
            created=str(header.get("created", "")),
            path=p,
        )

    @classmethod
    def load(
        cls,
        path: str | os.PathLike[str],
        config: MatchConfig | str | None = None,
        **options: Any,
    ) -> ShapeIndex:
        """Read an index, verify it and refuse one that does not fit this code.

        Parameters
        ----------
        path : path-like
        config : MatchConfig, str or None
            When given (or when ``options`` are), the configuration the caller means to
            use; the index must have been built with exactly it.
        **options
            :class:`MatchConfig` fields changed on top of ``config`` (on top of the
            index's own configuration when ``config`` is None).

        Raises
        ------
        ShapeTreeError
            The file is missing, damaged or truncated, was written by another shapetree
            version or code (the message says how to rebuild it), or was built with
            another configuration (the message names the options that differ).
        """
        index = cls._read(path)
        index._check_current()
        if config is not None or options:
            want = resolve_config(index.config if config is None else config, **options)
            index.check_config(want)
        return index

    # ------------------------------------------------------------ description

    def info(self) -> str:
        """A few lines describing the index (for ``shapetree index info``)."""
        version, fingerprint = _current()
        lines = []
        if self.path is not None:
            size = self.path.stat().st_size if self.path.exists() else 0
            lines.append(f"file:          {self.path} ({size / 1e6:.2f} MB)")
        lines.append(f"format:        {FORMAT} version {FORMAT_VERSION}")
        lines.append(f"shapes:        {len(self)}")
        pts = sorted({m.shape[0] for m in self.models})
        tpts = sorted({b.shape[0] for bs in self.targets for b in bs})
        phases = len(self.targets[0]) if self.targets else self.config.phases
        span = lambda v: "-" if not v else str(v[0]) if len(v) == 1 else f"{v[0]}..{v[-1]}"  # noqa: E731
        lines.append(
            f"samples:       {span(pts)} model points, {phases} target sampling(s) of {span(tpts)} "
            "points per shape"
        )
        desc = self.config.describe()
        if desc != "general preset":
            desc = f"general preset with {desc}"
        lines.append(f"configuration: {desc}")
        lines.append(f"built by:      shapetree {self.version} (code {self.fingerprint[:12]})")
        lines.append(f"created:       {self.created}")
        if (self.version, self.fingerprint) == (version, fingerprint):
            lines.append("usable:        yes (same version and code as this shapetree)")
        else:
            lines.append(
                f"usable:        no: this is shapetree {version} (code {fingerprint[:12]}); "
                f"rebuild it: shapetree index build {self.path or 'DB'} -o NEW{EXTENSION}"
            )
        return "\n".join(lines)
