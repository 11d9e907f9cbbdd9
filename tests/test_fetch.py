"""Tests of shapetree.datasets.fetch against a local HTTP server on 127.0.0.1.

Archives are built in tmp_path from tiny numpy-made PNGs; nothing leaves the machine.
"""

from __future__ import annotations

import functools
import hashlib
import io
import os
import tarfile
import threading
import zipfile
from collections.abc import Iterator
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from shapetree import DatasetError
from shapetree import datasets as ds
from shapetree.curves import signed_area


class _Handler(SimpleHTTPRequestHandler):
    """Serves a folder; ``/truncated/<file>`` announces the full length but sends half."""

    requests: list[str]

    def log_message(self, format: str, *args: object) -> None:  # noqa: A002
        pass

    def do_GET(self) -> None:  # noqa: N802
        self.requests.append(self.path)
        if self.path.startswith("/truncated/"):
            data = (Path(self.directory) / self.path.removeprefix("/truncated/")).read_bytes()
            self.send_response(200)
            self.send_header("Content-Length", str(len(data)))
            self.end_headers()
            self.wfile.write(data[: len(data) // 2])
            self.wfile.flush()
            self.close_connection = True
            return
        super().do_GET()


class _Server:
    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.requests: list[str] = []
        handler = type("H", (_Handler,), {"requests": self.requests, "timeout": 10})
        self.httpd = ThreadingHTTPServer(
            ("127.0.0.1", 0), functools.partial(handler, directory=str(folder))
        )
        self.httpd.daemon_threads = True
        self.thread = threading.Thread(
            target=self.httpd.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True
        )
        self.thread.start()

    def url(self, name: str) -> str:
        host, port = self.httpd.server_address[:2]
        return f"http://{host}:{port}/{name}"

    def close(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()
        self.thread.join(timeout=5)


@pytest.fixture
def server(tmp_path: Path) -> Iterator[_Server]:
    folder = tmp_path / "served"
    folder.mkdir()
    srv = _Server(folder)
    try:
        yield srv
    finally:
        srv.close()
    assert not srv.thread.is_alive()


@pytest.fixture
def data_root(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    root = tmp_path / "data"
    monkeypatch.setenv("SHAPETREE_DATA", str(root))
    monkeypatch.setenv("SHAPETREE_CACHE", str(tmp_path / "cache"))
    return root


def _png_bytes(r: int, fg: int = 0, bg: int = 255, size: int = 24) -> bytes:
    yy, xx = np.mgrid[:size, :size]
    img = np.where((yy - size / 2) ** 2 + (xx - size / 2) ** 2 <= r * r, fg, bg).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(img, mode="L").save(buf, format="PNG")
    return buf.getvalue()


def _members(labels: bool = True) -> dict[str, bytes]:
    files = {f"mini/s{i}.png": _png_bytes(4 + i) for i in range(4)}
    if labels:
        rows = "".join(f"s{i}.png,{'ab'[i % 2]}\n" for i in range(4))
        files["mini/labels.csv"] = ("filename,class\n" + rows).encode()
    return files


def _zip(path: Path, files: dict[str, bytes]) -> str:
    with zipfile.ZipFile(path, "w") as zf:
        for name, data in files.items():
            zf.writestr(name, data)
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _tgz(path: Path, files: dict[str, bytes]) -> str:
    with tarfile.open(path, "w:gz") as tf:
        for name, data in files.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            tf.addfile(info, io.BytesIO(data))
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _assert_nothing_left(root: Path, keep: tuple[str, ...] = ()) -> None:
    """The data root holds only ``keep``: no dataset folder, no temp file or folder."""
    left = sorted(p.name for p in root.iterdir()) if root.exists() else []
    assert left == sorted(keep)


# ----------------------------------------------------------------------------- success


@pytest.mark.parametrize("fmt", ["zip", "tar.gz", "tgz"])
def test_good_download_lands_and_loads(server: _Server, data_root: Path, fmt: str) -> None:
    archive = server.folder / f"mini.{fmt}"
    digest = (_zip if fmt == "zip" else _tgz)(archive, _members())
    out = ds.fetch("kimia99", url=server.url(archive.name), sha256=digest.upper(), progress=False)
    assert out == data_root / "kimia99"
    _assert_nothing_left(data_root, keep=("kimia99",))
    assert sorted(p.name for p in out.iterdir()) == [
        "labels.csv",
        "s0.png",
        "s1.png",
        "s2.png",
        "s3.png",
    ]
    d = ds.load("kimia99", n_points=30, progress=False)
    assert d.labels.tolist() == ["a", "b", "a", "b"]
    assert all(c.shape == (30, 2) and signed_area(c) > 0 for c in d.curves)
    info = {i.name: i for i in ds.available()}["kimia99"]
    assert info.present and info.count == 4 and not info.complete


def test_dest_argument_and_force(server: _Server, tmp_path: Path) -> None:
    dest = tmp_path / "elsewhere"
    digest = _zip(server.folder / "a.zip", _members())
    out = ds.fetch("kimia99", dest=dest, url=server.url("a.zip"), sha256=digest, progress=False)
    assert out == dest / "kimia99"
    (out / "marker").write_text("old copy")
    with pytest.raises(DatasetError, match="already exists"):
        ds.fetch("kimia99", dest=dest, url=server.url("a.zip"), sha256=digest, progress=False)
    assert (out / "marker").is_file()
    # a failing forced fetch keeps the old copy
    with pytest.raises(DatasetError, match="checksum mismatch"):
        ds.fetch(
            "kimia99",
            dest=dest,
            url=server.url("a.zip"),
            sha256="0" * 64,
            progress=False,
            force=True,
        )
    assert (out / "marker").is_file()
    _assert_nothing_left(dest, keep=("kimia99",))
    ds.fetch(
        "kimia99", dest=dest, url=server.url("a.zip"), sha256=digest, progress=False, force=True
    )
    assert not (out / "marker").exists() and (out / "labels.csv").is_file()
    _assert_nothing_left(dest, keep=("kimia99",))


def test_insecure_download_warns_with_digest(server: _Server, data_root: Path) -> None:
    digest = _zip(server.folder / "a.zip", _members())
    with pytest.raises(DatasetError, match="cannot be verified.*insecure"):
        ds.fetch("kimia99", url=server.url("a.zip"), progress=False)
    assert server.requests == []  # refused before downloading
    _assert_nothing_left(data_root)
    with pytest.warns(UserWarning, match=f"NOT verified.*{digest}"):
        ds.fetch("kimia99", url=server.url("a.zip"), progress=False, insecure=True)
    _assert_nothing_left(data_root, keep=("kimia99",))


def test_kimia_labels_from_source_classes_txt(server: _Server, data_root: Path) -> None:
    files = _members(labels=False)
    # the source's classes.txt: a Python-2 protocol-0 pickle of {filename: class id}
    entries = "".join(f"S's{i}.png'\np{i + 2}\nI{i % 2 + 8}\ns" for i in range(4))
    files["mini/classes.txt"] = f"(dp1\n{entries}.".encode()
    digest = _zip(server.folder / "k.zip", files)
    ds.fetch("kimia99", url=server.url("k.zip"), sha256=digest, progress=False)
    names, labels, _ = ds.load_labels("kimia99")
    assert dict(zip(names, labels.tolist(), strict=True)) == {
        "s0.png": "quadruped",
        "s1.png": "ray",
        "s2.png": "quadruped",
        "s3.png": "ray",
    }


def test_mpeg7_layout_without_labels(server: _Server, data_root: Path) -> None:
    files = {
        f"Part-B/1-Similarity/{n}": _png_bytes(5, fg=255, bg=0)
        for n in ("cup-1.png", "cup-02.png", "Bone-1.png")
    }
    digest = _tgz(server.folder / "m.tar.gz", files)
    out = ds.fetch("mpeg7", url=server.url("m.tar.gz"), sha256=digest, progress=False)
    assert (out / "labels.csv").read_text().splitlines() == [
        "filename,class",
        "Bone-1.png,Bone",
        "cup-1.png,cup",
        "cup-02.png,cup",
    ]
    assert len(ds.load("mpeg7", n_points=20, progress=False)) == 3


def test_swedish_source_layout(server: _Server, data_root: Path) -> None:
    files = {f"swedish_png-x/l{s}nr00{i}.png": _png_bytes(6) for s in (2, 10) for i in (1, 2)}
    digest = _zip(server.folder / "s.zip", files)
    out = ds.fetch("swedish_leaf", url=server.url("s.zip"), sha256=digest, progress=False)
    assert sorted(p.name for p in (out / "source_png_fullres").iterdir()) == sorted(
        n.split("/")[1] for n in files
    )
    d = ds.load("swedish_leaf", n_points=20, progress=False)
    assert d.images_dir == out / "source_png_fullres"
    assert d.names == ["l2nr001.png", "l2nr002.png", "l10nr001.png", "l10nr002.png"]
    assert d.labels.tolist() == ["Acer"] * 2 + ["Sorbus aucuparia"] * 2


def _jpeg_bytes() -> bytes:
    buf = io.BytesIO()
    Image.fromarray(np.zeros((10, 12, 3), np.uint8)).save(buf, format="JPEG")
    return buf.getvalue()


def test_ethz_layout(server: _Server, data_root: Path) -> None:
    from shapetree.datasets._registry import ETHZ_CLASSES

    top = "ETHZShapeClasses-V1.2"
    files = {}
    for cls, (tag, model) in ETHZ_CLASSES.items():
        files[f"{top}/{cls}/im.jpg"] = _jpeg_bytes()
        files[f"{top}/{cls}/im_edges.tif"] = _png_bytes(3)  # content is not parsed
        files[f"{top}/{cls}/im_{tag}.groundtruth"] = b"1 2 5 6 \n"
        files[f"{top}/models/{model}.tif"] = _png_bytes(3)
    digest = _tgz(server.folder / "ethz_shape_classes_v12.tgz", files)
    out = ds.fetch(
        "ethz_shape", url=server.url("ethz_shape_classes_v12.tgz"), sha256=digest, progress=False
    )
    assert (out / top / "Mugs" / "im.jpg").is_file()
    images = ds.load_ethz()
    assert len(images) == 5 and all(i.boxes.tolist() == [[1, 2, 5, 6]] for i in images)
    assert ds.ethz_model_path("swans") == out / top / "models" / "swan.tif"
    _assert_nothing_left(data_root, keep=("ethz_shape",))


# ----------------------------------------------------------------------------- failures


def test_wrong_checksum_leaves_nothing(server: _Server, data_root: Path) -> None:
    _zip(server.folder / "a.zip", _members())
    with pytest.raises(DatasetError, match="checksum mismatch"):
        ds.fetch("kimia99", url=server.url("a.zip"), sha256="ab" * 32, progress=False)
    _assert_nothing_left(data_root)


def test_404_leaves_nothing(server: _Server, data_root: Path) -> None:
    with pytest.raises(DatasetError, match="HTTP 404"):
        ds.fetch("kimia99", url=server.url("missing.zip"), sha256="ab" * 32, progress=False)
    _assert_nothing_left(data_root)


def test_truncated_transfer_leaves_nothing(server: _Server, data_root: Path) -> None:
    digest = _zip(server.folder / "a.zip", _members())
    with pytest.raises(DatasetError, match="truncated"):
        ds.fetch("kimia99", url=server.url("truncated/a.zip"), sha256=digest, progress=False)
    _assert_nothing_left(data_root)


@pytest.mark.parametrize("fmt", ["zip", "tar.gz"])
def test_truncated_archive_leaves_nothing(server: _Server, data_root: Path, fmt: str) -> None:
    """A cut archive whose (matching) checksum was given still fails in extraction."""
    full = server.folder / f"full.{fmt}"
    (_zip if fmt == "zip" else _tgz)(full, _members())
    cut = server.folder / f"cut.{fmt}"
    cut.write_bytes(full.read_bytes()[: full.stat().st_size * 2 // 3])
    digest = hashlib.sha256(cut.read_bytes()).hexdigest()
    with pytest.raises(DatasetError, match="cannot extract"):
        ds.fetch("kimia99", url=server.url(cut.name), sha256=digest, progress=False)
    _assert_nothing_left(data_root)


def test_archive_without_usable_dataset(server: _Server, data_root: Path) -> None:
    files = _members()
    del files["mini/s3.png"]  # listed in labels.csv but absent
    digest = _zip(server.folder / "a.zip", files)
    with pytest.raises(DatasetError, match=r"does not hold a usable 'kimia99'.*s3\.png"):
        ds.fetch("kimia99", url=server.url("a.zip"), sha256=digest, progress=False)
    _assert_nothing_left(data_root)
    digest = _zip(server.folder / "b.zip", {"readme.txt": b"nothing here"})
    with pytest.raises(DatasetError, match="no .png"):
        ds.fetch("kimia99", url=server.url("b.zip"), sha256=digest, progress=False)
    _assert_nothing_left(data_root)


def test_unsafe_member_refused(server: _Server, data_root: Path, tmp_path: Path) -> None:
    files = _members()
    files["../evil.png"] = b"x"
    digest = _zip(server.folder / "a.zip", files)
    with pytest.raises(DatasetError, match="unsafe member"):
        ds.fetch("kimia99", url=server.url("a.zip"), sha256=digest, progress=False)
    _assert_nothing_left(data_root)
    assert not (tmp_path / "evil.png").exists()


def test_refusals_without_network(data_root: Path) -> None:
    with pytest.raises(DatasetError) as e:
        ds.fetch("mpeg7", progress=False)
    msg = str(e.value)
    assert ".rar" in msg and "unar" in msg and "200ce979" in msg
    assert "Part-B/1-Similarity" in msg
    with pytest.raises(DatasetError, match="cannot tell the archive format"):
        ds.fetch("kimia99", url="http://127.0.0.1:9/data.7z", sha256="ab" * 32, progress=False)
    with pytest.raises(DatasetError, match="64 hexadecimal"):
        ds.fetch("kimia99", url="http://127.0.0.1:9/a.zip", sha256="xyz", progress=False)
    with pytest.raises(DatasetError, match="cannot be verified"):
        ds.fetch("swedish_leaf", progress=False)
    with pytest.raises(DatasetError, match="unknown dataset"):
        ds.fetch("nope", progress=False)
    _assert_nothing_left(data_root)


def test_connection_refused_leaves_nothing(data_root: Path) -> None:
    import socket

    with socket.socket() as s:  # a port that is closed once we release it
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(DatasetError, match="download of .* failed"):
        ds.fetch(
            "kimia99",
            url=f"http://127.0.0.1:{port}/a.zip",
            sha256="ab" * 32,
            progress=False,
            timeout=5,
        )
    _assert_nothing_left(data_root)
    assert os.environ["SHAPETREE_DATA"] == str(data_root)
