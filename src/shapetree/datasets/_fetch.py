"""Downloading datasets: verified, extracted atomically, never half-installed.

Procedure of :func:`fetch`:

1. Refuse early if the archive is a ``.rar`` (the standard library cannot extract
   it; the error explains the manual steps) or if no checksum is known and the
   caller gave none (unless ``insecure=True``).
2. Stream the archive into a hidden temporary file in the destination folder,
   hashing as it goes; a short body (fewer bytes than ``Content-Length``), an
   HTTP error or a network error aborts.
3. Compare the digest with the expected SHA-256 (or the registry's published
   SHA-1 where that is the only one known).
4. Extract into a hidden temporary folder next to the destination (members with
   absolute paths or ``..`` are refused), rearrange into the layout
   :func:`shapetree.datasets.load` expects (writing ``labels.csv`` where the
   source has none), check that it loads, and only then :func:`os.replace` it to
   ``<dest>/<name>``.
5. Whatever happens, remove the temporary file and folder.
"""

from __future__ import annotations

import csv
import hashlib
import http.client
import os
import re
import shutil
import tarfile
import tempfile
import urllib.error
import urllib.parse
import urllib.request
import warnings
import zipfile
from collections.abc import Callable
from pathlib import Path, PurePosixPath

from shapetree._errors import DatasetError
from shapetree.datasets._registry import (
    KIMIA99_CLASS_NAMES,
    SWEDISH_SPECIES,
    data_dir,
    get_spec,
)

__all__ = ["fetch"]

_CHUNK = 1 << 16
_HEX = re.compile(r"^[0-9a-fA-F]+$")
_MPEG7_NAME = re.compile(r"^(?P<cls>.+)-(?P<num>\d+)\.png$")
_SWEDISH_NAME = re.compile(r"^l(?P<s>\d+)nr(?P<n>\d+)\.png$")
# One "filename -> class id" entry of a protocol-0 pickle: Python 2 writes S'name', Python 3 Vname.
_KIMIA_ENTRY = re.compile(
    r"(?:S'(?P<file>[^'\n]+\.png)'|V(?P<vfile>[^\n]+\.png))\s*\n(?:p\d+\s*\n)?I(?P<id>\d+)"
)


def _archive_kind(url: str) -> str:
    path = urllib.parse.urlparse(url).path.lower()
    for suffix, kind in (
        (".tar.gz", "tar.gz"),
        (".tgz", "tar.gz"),
        (".tar", "tar"),
        (".zip", "zip"),
        (".rar", "rar"),
    ):
        if path.endswith(suffix):
            return kind
    raise DatasetError(
        f"cannot tell the archive format of {url}: supported are .zip, .tar.gz, .tgz and .tar"
    )


def _rar_message(name: str, url: str, sha256: str | None, dest: Path) -> str:
    check = f" (sha256 {sha256})" if sha256 else ""
    return (
        f"the public source of {name!r} is a .rar archive, which Python's standard library "
        "cannot extract. Manual steps: (1) download "
        f"{url}{check}; (2) check it with `sha256sum`; (3) extract it with `unar` or "
        "`unrar x`; (4) copy the images into "
        f"{dest / name}/ (for mpeg7: the 1400 files Part-B/1-Similarity/*.png; labels are "
        "taken from the file names when labels.csv is absent). Or repack the images as "
        f".zip/.tar.gz and run fetch({name!r}, url=..., sha256=...)."
    )


def _download(url: str, out: Path, algo: str, progress: bool, timeout: float) -> tuple[str, str]:
    """Stream ``url`` into ``out``; return (digest in ``algo``, sha256)."""
    h = hashlib.new(algo)
    h256 = h if algo == "sha256" else hashlib.sha256()
    try:
        with urllib.request.urlopen(url, timeout=timeout) as resp:
            length_hdr = resp.headers.get("Content-Length")
            length = int(length_hdr) if length_hdr and length_hdr.isdigit() else None
            from tqdm.auto import tqdm

            got = 0
            with (
                open(out, "wb") as f,
                tqdm(
                    total=length,
                    unit="B",
                    unit_scale=True,
                    desc=f"downloading {PurePosixPath(urllib.parse.urlparse(url).path).name}",
                    disable=not progress,
                ) as bar,
            ):
                while True:
                    chunk = resp.read(_CHUNK)
                    if not chunk:
                        break
                    f.write(chunk)
                    h.update(chunk)
                    if h256 is not h:
                        h256.update(chunk)
                    got += len(chunk)
                    bar.update(len(chunk))
            if length is not None and got != length:
                raise DatasetError(f"download of {url} is truncated: got {got} of {length} bytes")
    except urllib.error.HTTPError as e:
        raise DatasetError(f"download of {url} failed: HTTP {e.code} {e.reason}") from e
    except http.client.IncompleteRead as e:
        raise DatasetError(
            f"download of {url} is truncated: got {len(e.partial)} more bytes, "
            f"expected {e.expected} more"
        ) from e
    except (urllib.error.URLError, OSError, http.client.HTTPException) as e:
        raise DatasetError(f"download of {url} failed: {e}") from e
    return h.hexdigest(), h256.hexdigest()


def _safe_member(name: str, archive: str) -> None:
    p = PurePosixPath(name.replace("\\", "/"))
    if p.is_absolute() or ".." in p.parts or re.match(r"^[A-Za-z]:", name):
        raise DatasetError(f"{archive}: refusing unsafe member path {name!r}")


def _extract(archive: Path, kind: str, into: Path, label: str) -> None:
    try:
        if kind == "zip":
            with zipfile.ZipFile(archive) as zf:
                for m in zf.namelist():
                    _safe_member(m, label)
                bad = zf.testzip()
                if bad is not None:
                    raise DatasetError(f"{label}: archive member {bad!r} is corrupt")
                zf.extractall(into)
        else:
            mode = "r:gz" if kind == "tar.gz" else "r:"
            with tarfile.open(archive, mode) as tf:
                for m in tf.getmembers():
                    _safe_member(m.name, label)
                tf.extractall(into, filter="data")
    except DatasetError:
        raise
    except (zipfile.BadZipFile, tarfile.TarError, EOFError, OSError, ValueError) as e:
        raise DatasetError(f"{label}: cannot extract {kind} archive ({e})") from e


def _find_dir(top: Path, pred: Callable[[Path], bool]) -> Path | None:
    """Shallowest directory under ``top`` (itself included) satisfying ``pred``."""
    level = [top]
    while level:
        hits = [d for d in level if pred(d)]
        if hits:
            return sorted(hits)[0]
        nxt: list[Path] = []
        for d in level:
            nxt.extend(sorted(p for p in d.iterdir() if p.is_dir() and not p.is_symlink()))
        level = nxt
    return None


def _write_csv(path: Path, header: list[str], rows: list[list[object]]) -> None:
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(header)
        w.writerows(rows)


def _has_png(d: Path) -> bool:
    return any(d.glob("*.png"))


def _arrange_mpeg7(content: Path) -> None:
    if (content / "labels.csv").is_file():
        return
    rows = []
    for p in content.glob("*.png"):
        m = _MPEG7_NAME.match(p.name)
        if m is None:
            raise DatasetError(f"archive file {p.name!r} is not named <class>-<n>.png")
        rows.append((m.group("cls"), int(m.group("num")), p.name))
    rows.sort()
    _write_csv(content / "labels.csv", ["filename", "class"], [[f, c] for c, _, f in rows])


def _arrange_kimia99(content: Path) -> None:
    if (content / "labels.csv").is_file():
        return
    src = content / "classes.txt"
    if not src.is_file():
        raise DatasetError("archive has neither labels.csv nor the source's classes.txt")
    # classes.txt is a protocol-0 pickle of {filename: class_id}; parse it as text.
    text = src.read_text(encoding="latin-1")
    entries = [
        (m.group("file") or m.group("vfile"), int(m.group("id")))
        for m in _KIMIA_ENTRY.finditer(text)
    ]
    if not entries:
        raise DatasetError("classes.txt: no 'filename -> class id' entries found")
    bad = sorted({i for _, i in entries} - set(KIMIA99_CLASS_NAMES))
    if bad:
        raise DatasetError(f"classes.txt: unknown class ids {bad}")
    entries.sort(key=lambda e: (e[1], e[0]))
    _write_csv(
        content / "labels.csv",
        ["filename", "class"],
        [[f, KIMIA99_CLASS_NAMES[i]] for f, i in entries],
    )


def _arrange_swedish(content: Path) -> None:
    images = None
    for sub in ("png512", "source_png_fullres"):
        if (content / sub).is_dir():
            images = content / sub
            break
    if images is None:
        images = content / "source_png_fullres"
        images.mkdir()
        for p in list(content.glob("*.png")):
            if _SWEDISH_NAME.match(p.name):
                os.replace(p, images / p.name)
    if (content / "labels.csv").is_file():
        return
    rows = []
    for p in images.glob("*.png"):
        m = _SWEDISH_NAME.match(p.name)
        if m is None:
            continue
        s = int(m.group("s"))
        if s not in SWEDISH_SPECIES:
            raise DatasetError(f"archive file {p.name!r} has unknown species {s}")
        rows.append([p.name, s, int(m.group("n")), SWEDISH_SPECIES[s]])
    if not rows:
        raise DatasetError("archive holds no l<species>nr<NNN>.png images")
    rows.sort(key=lambda r: (r[1], r[2]))
    _write_csv(content / "labels.csv", ["filename", "species", "image", "species_name"], rows)


def _arrange(name: str, extracted: Path, staging: Path) -> None:
    """Move the dataset's content from ``extracted`` to ``staging`` in load()'s layout."""
    spec = get_spec(name)
    if name == "ethz_shape":
        classes = spec.classes
        sub = spec.images_subdir
        content = _find_dir(
            extracted,
            lambda d: (d / sub).is_dir() or all((d / c).is_dir() for c in classes),
        )
        if content is None:
            raise DatasetError(f"archive holds no {sub}/ folder")
        if (content / sub).is_dir():
            os.replace(content, staging)
        else:
            staging.mkdir()
            os.replace(content, staging / sub)
        return
    if name == "swedish_leaf":
        content = _find_dir(
            extracted,
            lambda d: (
                (d / "png512").is_dir()
                or (d / "source_png_fullres").is_dir()
                or any(_SWEDISH_NAME.match(p.name) for p in d.glob("*.png"))
            ),
        )
    else:
        content = _find_dir(extracted, lambda d: (d / "labels.csv").is_file() and _has_png(d))
        if content is None:
            content = _find_dir(extracted, _has_png)
    if content is None:
        raise DatasetError("archive holds no .png images")
    os.replace(content, staging)
    {"mpeg7": _arrange_mpeg7, "kimia99": _arrange_kimia99, "swedish_leaf": _arrange_swedish}[name](
        staging
    )


def _validate(name: str, staging: Path) -> None:
    if name == "ethz_shape":
        from shapetree.datasets._ethz import load_ethz

        load_ethz(staging)
    else:
        from shapetree.datasets._load import load_labels

        load_labels(name, root=staging)


def _expected_digest(
    spec_sha256: str | None,
    spec_sha1: str | None,
    sha256: str | None,
    url_given: bool,
) -> tuple[str, str] | None:
    if sha256 is not None:
        s = sha256.strip().lower()
        if len(s) != 64 or not _HEX.match(s):
            raise DatasetError(f"sha256 must be 64 hexadecimal digits, got {sha256!r}")
        return "sha256", s
    if not url_given and spec_sha256:
        return "sha256", spec_sha256.lower()
    if not url_given and spec_sha1:
        return "sha1", spec_sha1.lower()
    return None


def fetch(
    name: str,
    *,
    dest: str | os.PathLike[str] | None = None,
    url: str | None = None,
    sha256: str | None = None,
    progress: bool = True,
    insecure: bool = False,
    force: bool = False,
    timeout: float = 60.0,
) -> Path:
    """Download a dataset, verify it, and install it atomically.

    Parameters
    ----------
    name : str
        ``mpeg7``, ``kimia99``, ``swedish_leaf`` or ``ethz_shape``.
    dest : path-like, optional
        Data root; the dataset goes to ``<dest>/<name>``. Default :func:`data_dir`.
    url : str, optional
        Archive address (``http(s)://`` or ``file://``); default the registry's
        public source. Format from the suffix: ``.zip``, ``.tar.gz``/``.tgz``, ``.tar``.
    sha256 : str, optional
        Expected SHA-256 of the archive. Default: the registry's checksum when
        ``url`` is not given (SHA-256, or the published SHA-1 for ETHZ).
    progress : bool, default True
        Show a tqdm progress bar.
    insecure : bool, default False
        Allow a download whose checksum is unknown (no ``sha256`` given and none
        in the registry: kimia99 and swedish_leaf, whose sources are GitHub
        archive zips, or any custom ``url``). A warning then reports the
        archive's SHA-256 so it can be pinned next time.
    force : bool, default False
        Replace an existing ``<dest>/<name>`` (only after the new copy is ready).
    timeout : float, default 60
        Network timeout in seconds.

    Returns
    -------
    pathlib.Path
        The installed dataset folder ``<dest>/<name>``.

    Raises
    ------
    DatasetError
        Unknown name; ``.rar`` source (the message gives the manual steps);
        no checksum and not ``insecure``; destination exists and not ``force``;
        HTTP/network error, truncated download, checksum mismatch, bad or
        unsafe archive, or an archive that does not hold a loadable dataset.
        In every failure case no ``<dest>/<name>`` is created (an existing one
        is left untouched) and all temporary files are removed.
    """
    spec = get_spec(name)
    src = spec.source
    the_url = url if url is not None else src.url
    kind = _archive_kind(the_url)
    root = Path(dest).expanduser() if dest is not None else data_dir()
    final = root / name
    if kind == "rar":
        raise DatasetError(_rar_message(name, the_url, sha256 or src.sha256, root))
    expected = _expected_digest(src.sha256, src.sha1, sha256, url is not None)
    if expected is None and not insecure:
        raise DatasetError(
            f"no checksum is known for {the_url}, so the download cannot be verified; pass "
            "sha256=... (CLI: --sha256 HEX) or insecure=True (CLI: --insecure) to accept it "
            "unverified"
        )
    if final.exists() and not force:
        raise DatasetError(
            f"{final} already exists; remove it or pass force=True (CLI: --force) to replace it"
        )
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise DatasetError(f"cannot create destination folder {root}: {e}") from e

    algo = expected[0] if expected else "sha256"
    fd, tmp_name = tempfile.mkstemp(dir=root, prefix=f".{name}.", suffix=".download")
    os.close(fd)
    tmp_file = Path(tmp_name)
    work = Path(tempfile.mkdtemp(dir=root, prefix=f".{name}.", suffix=".extract"))
    try:
        digest, digest256 = _download(the_url, tmp_file, algo, progress, timeout)
        if expected is not None and digest != expected[1]:
            raise DatasetError(
                f"checksum mismatch for {the_url}: expected {algo} {expected[1]}, got {digest}"
            )
        if expected is None:
            warnings.warn(
                f"{the_url} was NOT verified (insecure=True); its sha256 is {digest256}",
                stacklevel=2,
            )
        extracted = work / "extracted"
        extracted.mkdir()
        _extract(tmp_file, kind, extracted, the_url)
        tmp_file.unlink()
        staging = work / name
        _arrange(name, extracted, staging)
        try:
            _validate(name, staging)
        except DatasetError as e:
            raise DatasetError(f"{the_url} does not hold a usable {name!r} dataset: {e}") from e
        if final.exists():  # force=True: move the old copy aside, then swap
            os.replace(final, work / "previous")
        os.replace(staging, final)
    finally:
        tmp_file.unlink(missing_ok=True)
        shutil.rmtree(work, ignore_errors=True)
    return final
