"""The all-pairs engine on a real ``dask.distributed`` LocalCluster (2 worker processes).

Bitwise equality with the threaded engine, a worker process killed mid-run, resumption from
the block cache across both engines, and the errors of a bad ``scheduler=``.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import distributed  # the "test" extra installs dask[distributed] (and psutil with it)
import numpy as np
import psutil
import pytest

from shapetree import ShapeTreeError
from shapetree.retrieval import _dask, combine, directed_costs, distance_matrix

#: the literal matcher, small samplings: every test here takes about a second
CFG = dict(config="paper", n_points=20, mirror=True)


def _shapes(k: int, n: int = 48, seed: int = 0) -> list[np.ndarray]:
    """Smooth random star-shaped closed curves, counter-clockwise."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    out = []
    for _ in range(k):
        r = 1 + sum(rng.uniform(-0.25, 0.25) * np.cos(f * t + rng.uniform(0, 6)) for f in (2, 3, 5))
        out.append(np.c_[r * np.cos(t) * rng.uniform(0.6, 1.4), r * np.sin(t)])
    return out


def _children() -> set[int]:
    """Child processes of this one, less multiprocessing's resource tracker (started once,
    kept for the interpreter's life)."""
    out = set()
    for p in psutil.Process().children(recursive=True):
        try:
            if "resource_tracker" not in " ".join(p.cmdline()):
                out.add(p.pid)
        except psutil.Error:  # it has just exited
            pass
    return out


@pytest.fixture(scope="module")
def client():
    before = _children()
    cluster = _dask.local_cluster(2)  # scheduler="local:2"'s cluster: no dashboard
    c = distributed.Client(cluster, set_as_default=False)
    try:
        yield c
    finally:
        c.close()
        cluster.close()
        deadline = time.time() + 30
        while _children() - before and time.time() < deadline:
            time.sleep(0.1)
        assert not _children() - before, "the LocalCluster left processes behind"


def test_square_matrix_bitwise_equal_and_progress(client, capsys) -> None:
    curves = _shapes(12)
    kw = dict(CFG, symmetrize="min", block=2)
    ref = distance_matrix(curves, workers=2, progress=False, **kw)
    stats: dict = {}
    got = directed_costs(curves, scheduler=client, stats=stats, progress=True, **CFG, block=2)
    assert stats["engine"] == "dask" and stats["pairs_computed"] == 144
    assert got.shape == (2, 12, 12)
    assert np.array_equal(np.minimum(got.min(0), got.min(0).T), ref)
    err = capsys.readouterr().err
    assert "144/144" in err and "dask 2 workers" in err  # the bar counted every pair
    # default block size from the cluster's 2 threads: the threaded one with workers=2
    assert np.array_equal(distance_matrix(curves, scheduler=client, progress=False, **kw), ref)
    assert client.status == "running"  # a client given by the caller stays open
    # the scheduler's address: connected to for the call, then disconnected
    address = client.scheduler.address
    assert address.startswith("tcp://127.0.0.1:")
    assert np.array_equal(distance_matrix(curves, scheduler=address, progress=False, **kw), ref)
    # one DaskScheduler shared by several calls
    with _dask.open_scheduler(client) as sched:
        assert np.array_equal(distance_matrix(curves, scheduler=sched, progress=False, **kw), ref)
    assert client.status == "running"


@pytest.mark.parametrize("symmetrize", ["min", "none", "reverse", "mean"])
def test_query_database_bitwise_equal(client, symmetrize) -> None:
    curves = _shapes(14, seed=1)
    q, db = curves[:4], curves[4:]
    kw = dict(CFG, symmetrize=symmetrize, block=3, progress=False)
    ref = distance_matrix(q, db, workers=2, **kw)
    got = distance_matrix(q, db, scheduler=client, **kw)
    assert got.shape == (4, 10) and got.dtype == ref.dtype
    assert np.array_equal(got, ref)


def test_finished_run_cancels_nothing(client) -> None:
    """A run whose blocks all finished sends the scheduler no ``cancel``: cancelling released
    keys makes it broadcast to every client, which can fail a connecting client's handshake
    (the CI failure of stop 41, ``assert len(msg) == 1``)."""

    def cancels() -> int:
        return sum(m.get("action") == "cancel" for _, m in client.get_events(client.id))

    before = cancels()
    curves = _shapes(6, seed=3)
    kw = dict(CFG, symmetrize="min", block=2, progress=False)
    assert np.array_equal(
        distance_matrix(curves, scheduler=client, **kw), distance_matrix(curves, **kw)
    )
    # a cancel travels on the client's batched stream (sent every few ms, not awaited): give
    # one the time to arrive before looking for it in the scheduler's event log
    time.sleep(0.5)
    client.sync(client.scheduler.identity)
    assert cancels() == before


def test_handshake_retried() -> None:
    """distributed's handshake race (a broadcast in the new client's first batch) is tried
    again, and a cluster that always fails it gives a sentence, not an AssertionError."""
    calls: list[object] = []
    fails = [_dask.CONNECT_TRIES - 1]

    class Flaky:
        def __init__(self, target, timeout, set_as_default):
            calls.append(target)
            if len(calls) <= fails[0]:
                raise AssertionError

    fake = type("d", (), {"Client": Flaky})
    assert isinstance(_dask._connect(fake, "tcp://here:1", "1s"), Flaky)
    assert calls == ["tcp://here:1"] * _dask.CONNECT_TRIES
    calls.clear()
    fails[0] = _dask.CONNECT_TRIES  # every try fails now
    with pytest.raises(ShapeTreeError, match="handshake with 'tcp://here:1' failed 3 times"):
        _dask._connect(fake, "tcp://here:1", "1s")


def test_height_fusion_bitwise_equal(client, tmp_path: Path) -> None:
    """``height_weight``: the blocks carry a layer of height-function distances, computed
    on the workers from descriptors sent with the targets; the cluster's matrix (and the
    cache it writes, read back by the threads) is the threaded one, bit for bit."""
    curves = _shapes(9, seed=2)
    kw = dict(CFG, symmetrize="mean", height_weight=0.4, height_points=24, block=2, progress=False)
    ref = distance_matrix(curves, workers=2, **kw)
    got = distance_matrix(curves, scheduler=client, cache_dir=tmp_path, **kw)
    assert np.array_equal(got, ref)
    stats: dict = {}
    kw.pop("symmetrize")
    again = directed_costs(curves, workers=2, cache_dir=tmp_path, stats=stats, **kw)
    assert stats["blocks_cached"] == stats["blocks"] and again.shape == (3, 9, 9)
    assert np.array_equal(combine(again, "mean", 0.4), ref)
    kw["symmetrize"] = "mean"
    assert np.array_equal(distance_matrix(curves[:3], curves, scheduler=client, **kw), ref[:3])


def test_local_cluster_string_starts_and_closes(tmp_path: Path) -> None:
    curves = _shapes(10, seed=2)
    before = _children()
    kw = dict(CFG, symmetrize="min", block=2, progress=False)
    ref = distance_matrix(curves[:3], curves[3:], workers=1, **kw)
    got = distance_matrix(curves[:3], curves[3:], scheduler="local:2", cache_dir=tmp_path, **kw)
    assert np.array_equal(got, ref)
    assert len(list(tmp_path.glob("*/*.blk"))) == 2 + 4  # both directions, cached here
    deadline = time.time() + 30
    while _children() - before and time.time() < deadline:
        time.sleep(0.1)
    assert not _children() - before, "scheduler='local:2' left processes behind"


def _run_in_thread(fn, *args, **kw) -> tuple[threading.Thread, dict]:
    box: dict = {}

    def target() -> None:
        try:
            box["result"] = fn(*args, **kw)
        except BaseException as exc:  # handed to the test thread
            box["error"] = exc

    th = threading.Thread(target=target, daemon=True)
    th.start()
    return th, box


def _kill_after_first_block(client, cache: Path, box: dict, which: str) -> tuple[list, int]:
    """Wait for the first block file, then SIGKILL one (or both) worker processes."""
    pids = sorted(client.run(os.getpid).values())
    assert len(pids) == 2
    deadline = time.time() + 60
    while not list(cache.glob("*/*.blk")) and time.time() < deadline and not box:
        time.sleep(0.002)
    n_at_kill = len(list(cache.glob("*/*.blk")))
    victims = pids[:1] if which == "one" else pids
    for pid in victims:
        os.kill(pid, signal.SIGKILL)
    return victims, n_at_kill


def test_resume_across_engines(client, tmp_path: Path) -> None:
    curves = _shapes(12, seed=3)
    kw = dict(CFG, block=2, progress=False)
    # dask writes, threads read: nothing computed
    a = tmp_path / "a"
    s1: dict = {}
    c1 = directed_costs(curves, scheduler=client, cache_dir=a, stats=s1, **kw)
    assert s1["pairs_computed"] == 144 and s1["blocks"] == 6
    s2: dict = {}
    c2 = directed_costs(curves, cache_dir=a, stats=s2, workers=2, **kw)
    assert s2["pairs_computed"] == 0 and s2["blocks_cached"] == 6 and s2["engine"] == "threads"
    assert np.array_equal(c1, c2)
    # threads write, dask reads: nothing submitted
    b = tmp_path / "b"
    directed_costs(curves, cache_dir=b, workers=2, **kw)
    s3: dict = {}
    c3 = directed_costs(curves, scheduler=client, cache_dir=b, stats=s3, **kw)
    assert s3["pairs_computed"] == 0 and s3["engine"] == "dask"
    assert np.array_equal(c3, c1)
    # a partial cache (a crashed client): only the missing blocks are computed
    blocks = sorted(next(a.iterdir()).glob("*.blk"))
    for p in blocks[1::2]:
        p.unlink()
    s4: dict = {}
    c4 = directed_costs(curves, scheduler=client, cache_dir=a, stats=s4, **kw)
    assert s4["pairs_computed"] == 3 * 2 * 12 and s4["blocks_cached"] == 3
    assert np.array_equal(c4, c1)


def test_worker_with_other_code_is_refused() -> None:
    curves = [np.c_[np.cos(t), np.sin(t)] for t in [np.linspace(0, 6.2, 20)]]
    with pytest.raises(ShapeTreeError, match="other shapetree code"):
        _dask._block_task(curves, ([curves], None), None, None, "0" * 64, (0, 1), None)


def test_failing_task_is_named(client) -> None:
    """A task that raises on the worker comes back, after its retries, as the
    ShapeTreeError it raised, or as one naming its rows (here: no configuration)."""
    from shapetree.matching import PRESETS

    sched, _ = _dask.check_scheduler(client)
    good = [np.c_[np.cos(t), np.sin(t)] for t in [np.linspace(0, 6, 20, endpoint=False)]]
    kw = dict(key="0" * 64, on_block=lambda *a: None)
    with pytest.raises(ShapeTreeError, match=r"task of rows 0:1 failed on a worker"):
        _dask.run_blocks(sched, good, [good], None, [(0, 1)], **kw)
    with pytest.raises(ShapeTreeError, match=r"got a 1-D array of shape \(7,\)"):
        _dask.run_blocks(sched, good, [[np.zeros(7)]], PRESETS["paper"], [(0, 1)], **kw)


@pytest.mark.parametrize(
    "bad, words",
    [
        ("local:0", "whole number of worker processes"),
        ("local:two", "whole number of worker processes"),
        ("local:", "whole number of worker processes"),
        ("threads", "not a Dask scheduler address"),
        ("tcp//host:8786", "not a Dask scheduler address"),
        (4, r"scheduler must be None \(threads\), a distributed.Client"),
        (object(), r"scheduler must be None \(threads\), a distributed.Client"),
    ],
)
def test_bad_scheduler_is_named(bad, words) -> None:
    with pytest.raises(ShapeTreeError, match=words):
        distance_matrix(_shapes(3), scheduler=bad, progress=False, **CFG)
    with pytest.raises(ShapeTreeError, match=words):
        directed_costs(_shapes(3), scheduler=bad, progress=False, **CFG)


def test_unreachable_address(monkeypatch) -> None:
    monkeypatch.setattr(_dask, "CONNECT_TIMEOUT", 1.0)
    with socket_port() as port:  # a port nobody listens on
        t0 = time.monotonic()
        with pytest.raises(ShapeTreeError, match="cannot reach the Dask scheduler at"):
            distance_matrix(_shapes(3), scheduler=f"tcp://127.0.0.1:{port}", progress=False, **CFG)
        assert time.monotonic() - t0 < 30


class socket_port:
    """A free TCP port on 127.0.0.1 (bound, not listening, while in use)."""

    def __enter__(self) -> int:
        import socket

        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        return self.sock.getsockname()[1]

    def __exit__(self, *exc: object) -> None:
        self.sock.close()


def test_closed_client_is_refused() -> None:
    c = distributed.Client(
        processes=False, n_workers=1, dashboard_address=None, set_as_default=False
    )
    c.close()
    with pytest.raises(ShapeTreeError, match="Client is closed"):
        distance_matrix(_shapes(3), scheduler=c, progress=False, **CFG)


def test_dask_not_installed_message(monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed fails
    with pytest.raises(ShapeTreeError, match=r'pip install "shapetree\[dask\]"'):
        distance_matrix(_shapes(3), scheduler="local:2", progress=False, **CFG)


def test_import_shapetree_does_not_import_dask() -> None:
    code = (
        "import sys, shapetree, shapetree.retrieval, shapetree.cli;"
        "print(sorted(m for m in ('dask', 'distributed') if m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    )
    assert out.stdout.strip() == "[]"


def _killed_run(client, tmp_path: Path, which: str) -> tuple[list[int], int]:
    """All pairs of 30 curves in 30 blocks on ``client``, killing ``which`` workers after the
    first block arrived: the matrix equals the threaded one, and every block is cached."""
    curves = _shapes(30, seed=5)
    kw = dict(config="paper", n_points=24, mirror=True, block=1, symmetrize="min")
    cache = tmp_path / "cache"
    th, box = _run_in_thread(
        distance_matrix, curves, scheduler=client, cache_dir=cache, progress=False, **kw
    )
    victims, n_at_kill = _kill_after_first_block(client, cache, box, which)
    th.join(120)
    assert not th.is_alive()
    assert "error" not in box, box.get("error")
    assert 1 <= n_at_kill < 30, "the run finished before a worker could be killed"
    ref = distance_matrix(curves, workers=2, progress=False, **kw)
    assert np.array_equal(box["result"], ref)
    assert len(list(cache.glob("*/*.blk"))) == 30
    return victims, n_at_kill


def test_worker_killed_mid_run_same_matrix(client, tmp_path: Path) -> None:
    """One worker process SIGKILLed mid-run: its task is rescheduled on the other."""
    victims, _ = _killed_run(client, tmp_path, "one")
    client.wait_for_workers(2, timeout=120)  # the nanny restarted the killed worker
    assert not set(client.run(os.getpid).values()) & set(victims)


def test_every_worker_killed_mid_run_same_matrix(tmp_path: Path) -> None:
    """Both worker processes SIGKILLed: the scattered targets are lost with them, and the
    remaining blocks are resubmitted with a fresh scatter once the nannies restarted them
    (a cluster of its own: a nanny may give up after this)."""
    before = _children()
    cluster = _dask.local_cluster(2)
    c = distributed.Client(cluster, set_as_default=False)
    try:
        _killed_run(c, tmp_path, "both")
    finally:
        c.close()
        cluster.close()
    deadline = time.time() + 30
    while _children() - before and time.time() < deadline:
        time.sleep(0.1)
    assert not _children() - before, "the LocalCluster left processes behind"


_CLIENT = """
import json, os, sys
sys.path.insert(0, {tests!r})
from test_dask import _shapes
from shapetree.retrieval import distance_matrix
from shapetree.retrieval._dask import open_scheduler
if __name__ == "__main__":
    with open_scheduler("local:2") as sched:
        pids = sorted(sched.client().run(os.getpid).values())
        open({pids!r}, "w").write(json.dumps(pids))
        distance_matrix(_shapes(30, seed=6), config="paper", n_points=24, block=1,
                        scheduler=sched, cache_dir={cache!r}, progress=False)
"""


def test_client_killed_mid_run_resumes(tmp_path: Path) -> None:
    """The client process (with its ``local:2`` cluster) SIGKILLed mid-run: its workers
    go with it, and a threaded run resumes from the blocks it wrote."""
    cache, pids_file = tmp_path / "cache", tmp_path / "pids.json"
    script = tmp_path / "client.py"
    script.write_text(
        _CLIENT.format(tests=str(Path(__file__).parent), pids=str(pids_file), cache=str(cache))
    )
    proc = subprocess.Popen([sys.executable, str(script)])
    try:
        deadline = time.time() + 120
        while time.time() < deadline and proc.poll() is None:
            if len(list(cache.glob("*/*.blk"))) >= 2:
                break
            time.sleep(0.005)
        assert proc.poll() is None, "the client finished before it could be killed"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(30)
    n_written = len(list(cache.glob("*/*.blk")))
    assert 2 <= n_written < 30
    workers = json.loads(pids_file.read_text())
    deadline = time.time() + 30
    while any(psutil.pid_exists(p) for p in workers) and time.time() < deadline:
        time.sleep(0.1)
    assert not any(psutil.pid_exists(p) for p in workers), "workers outlived their client"
    kw = dict(config="paper", n_points=24, block=1, progress=False, workers=2)
    stats: dict = {}
    resumed = directed_costs(_shapes(30, seed=6), cache_dir=cache, stats=stats, **kw)
    assert stats["blocks_cached"] >= n_written and stats["pairs_computed"] < 30 * 30
    assert np.array_equal(resumed, directed_costs(_shapes(30, seed=6), **kw))


# ---------------------------------------------------------------- the pruned search


@pytest.mark.parametrize("symmetrize", ["none", "mean", "reverse", "none+h", "reverse+h"])
def test_knn_bitwise_equal_and_cache_shared_with_threads(client, tmp_path, symmetrize) -> None:
    """``knn(scheduler=...)``: each block of queries is a task; the indices and distances
    are bitwise the threaded search's, which are the full matrix's ``k`` smallest per row
    (ties by index), and the blocks the cluster wrote are what a threaded run reads
    (``+h``: with the height-function fusion, whose descriptors go with the tasks)."""
    from shapetree.retrieval import knn

    curves = _shapes(16, seed=7)
    q, db = curves[:9], curves[4:]
    symmetrize, _, h = symmetrize.partition("+")
    fusion = dict(height_weight=0.6, height_points=20, height_complexity=True) if h else {}
    kw = dict(CFG, symmetrize=symmetrize, k=3, block=2, **fusion)
    ref_i, ref_d = knn(q, db, workers=2, **kw)
    stats: dict = {}
    got_i, got_d = knn(q, db, scheduler=client, cache_dir=tmp_path, stats=stats, **kw)
    assert stats["engine"] == "dask" and stats["blocks"] == 5 and stats["blocks_cached"] == 0
    assert stats["full"] < 9 * 12  # the bound pruned some pairs on the workers too
    assert np.array_equal(got_i, ref_i) and np.array_equal(got_d, ref_d)
    full = distance_matrix(
        q, db, workers=2, progress=False, **{**CFG, "symmetrize": symmetrize, **fusion}
    )
    order = np.argsort(full, axis=1, kind="stable")[:, :3]
    assert np.array_equal(ref_i, order)
    assert np.allclose(ref_d, np.take_along_axis(full, order, axis=1), rtol=1e-6, atol=0)
    again: dict = {}
    th_i, th_d = knn(q, db, workers=2, cache_dir=tmp_path, stats=again, **kw)
    assert again["blocks_cached"] == 5 and again["engine"] == "threads"
    assert np.array_equal(th_i, ref_i) and np.array_equal(th_d, ref_d)
    assert client.status == "running"


def test_knn_worker_with_other_code_is_refused() -> None:
    with pytest.raises(ShapeTreeError, match="other shapetree code"):
        _dask._knn_task((None,) * 3, (None,) * 3, (), "0" * 64, (0, 1), None)


def test_evaluate_neighbours_on_a_local_cluster(tmp_path) -> None:
    """``evaluate(neighbours=K, dask="local:2")``: the pruned search and the rows completed
    in full after it (a test leaf with no training leaf among its K nearest) run on one
    local cluster; the score is the threaded one."""
    from shapetree.datasets import load
    from shapetree.retrieval import evaluate

    classes = sorted(set(load("swedish_leaf", n_points=None, progress=False).labels))[:3]
    kw = dict(
        n_points=14,
        per_class=28,
        n_splits=3,
        classes=",".join(classes),
        neighbours=2,
        progress=False,
        verbose=False,
    )
    before = _children()
    ref = evaluate("swedish_leaf", "swedish_leaf", workers=2, **kw)
    got = evaluate("swedish_leaf", "swedish_leaf", dask="local:2", **kw)
    assert got["accuracy_splits"] == ref["accuracy_splits"]
    assert got["neighbours"]["engine"] == "dask" and ref["neighbours"]["engine"] == "threads"
    assert got["neighbours"]["rows_completed"] == ref["neighbours"]["rows_completed"] > 0
    assert got["pairs_computed"] == ref["pairs_computed"]
    deadline = time.time() + 30
    while _children() - before and time.time() < deadline:
        time.sleep(0.1)
    assert not _children() - before, "dask='local:2' left processes behind"
