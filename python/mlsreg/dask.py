"""Many registrations on a Dask cluster (``distributed``), each target built once per worker.

::

    from distributed import Client
    import mlsreg.dask

    client = Client("tcp://scheduler:8786")        # or LocalCluster(...); None: get_client()
    rows = mlsreg.dask.register_many("data/bunny/pairs.csv", client=client)
    for row in rows:                                # one PairResult per pair, in input order
        print(row.id, row.error or row.transform)

``pairs`` is a manifest path (CSV ``id,source,target[,gt][,init]`` as ``mlsreg eval`` reads it:
paths relative to the CSV's folder, gt and init 16 row-major numbers) or a sequence of rows,
each ``(source, target[, init[, gt]])`` or a dict with keys ``source``, ``target`` and optionally
``init``, ``gt``, ``id``. Sources and targets are file paths (read on the worker, so the workers
must see the same files), NumPy arrays or mlsreg.Cloud objects.

Design:

- **Grouped by target.** Each worker keeps the ``mlsreg.Target`` objects it built in an LRU cache
  bounded by ``cache_bytes`` (per worker; a target counts its ``memory_bytes``, ~176 bytes per
  point), keyed by the target's identity: path, modification time and size for a file, a
  content hash for an array or Cloud. ``worker_stats()`` and ``build_count()`` report builds.
- **Routed by target.** All pairs of one target go to one worker, chosen by rendezvous hashing of
  the target's key over the sorted worker addresses, with bounded loads (no worker gets more than
  1.25 times its share of the pairs while another has room; a target with more pairs than one
  worker's share is split over several workers). The restriction is loose
  (``allow_other_workers=True``): when that worker dies or leaves, its pairs run elsewhere (and
  build the target there), and Dask's work stealing may move pairs to an idle worker.
- **Failures are data.** A pair's exception is caught on the worker and returned in its row
  (``error``: ``"FileNotFoundError: ..."``); no task raises, so nothing is retried for it. Dask
  re-runs a task whose worker died on its own (up to ``distributed.scheduler.allowed-failures``
  times, 3 by default; then the row says ``"KilledWorker: ..."``).
- **Same results.** Each row's transform is bit-identical to ``mlsreg.register(source,
  mlsreg.Target(target), method, init, **params)`` in this process (registration and build
  results do not depend on the worker or the thread count).

``client=None`` uses ``distributed.get_client()`` when a client exists (e.g. after
``Client(...)``); otherwise, or with ``client=False``, the pairs run here, one after another,
with the same results (grouped by target, targets freed on return). Dask is needed only for a
cluster: ``import mlsreg.dask`` works without it.
"""

from __future__ import annotations

import collections
import csv
import dataclasses
import hashlib
import io
import json
import math
import os
import threading
import time
import uuid
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from . import Cloud, Target, evaluate, read_cloud, register

__all__ = ["PairResult", "register_many", "read_manifest", "worker_stats", "build_count",
           "clear_cache", "DEFAULT_CACHE_BYTES"]

DEFAULT_CACHE_BYTES = 2 << 30  # per worker
_BYTES_PER_POINT = 176  # when a target does not say (docs/operations.md, Capacity planning)
_LOAD_FACTOR = 1.25  # bounded-load routing: a worker's pairs over its fair share


@dataclasses.dataclass
class PairResult:
    """One pair of register_many: its transform (or the error that stopped it) and how it ran.

    ``error`` is None or ``"ExceptionType: message"`` (``"cancelled"`` when the progress callback
    stopped the batch first); ``rotation_error_deg``, ``translation_error_d``, ``rmse_d`` and
    ``success`` compare with the pair's ``gt`` (None without one); ``seconds`` is the pair's time
    on its worker (reading the source, building the target unless cached, registering);
    ``worker`` the address of the Dask worker that ran it (None when run in this process)."""

    index: int
    id: Optional[str] = None
    transform: Optional[np.ndarray] = dataclasses.field(default=None, repr=False)
    verified: Optional[bool] = None
    verdict: Optional[str] = None
    termination: Optional[str] = None
    iterations: Optional[int] = None
    error: Optional[str] = None
    rotation_error_deg: Optional[float] = None
    translation_error_d: Optional[float] = None
    rmse_d: Optional[float] = None
    success: Optional[bool] = None
    seconds: float = 0.0
    worker: Optional[str] = None
    target_key: Optional[str] = dataclasses.field(default=None, repr=False)
    target_built: bool = dataclasses.field(default=False, repr=False)

    @property
    def ok(self) -> bool:
        return self.error is None


# ---- inputs

@dataclasses.dataclass
class _Job:
    index: int
    id: Optional[str]
    source: Any
    target: Any  # a path (str), or the object to build a Target from
    init: Optional[np.ndarray]
    gt: Optional[np.ndarray]
    target_key: Optional[str] = None  # the cache key; for files decided on the worker
    route_key: Optional[str] = None  # what routing hashes (stable across calls)
    error: Optional[str] = None  # the row could not be read


def _matrix(value) -> Optional[np.ndarray]:
    if value is None:
        return None
    return np.array(value, dtype=np.float64)  # a copy: the shape is checked where it is used


def _parse_transform(text: str, what: str, base: str) -> np.ndarray:
    fields = text.replace(",", " ").split()
    try:
        numbers = [float(v) for v in fields]
    except ValueError:
        path = text if os.path.isabs(text) else os.path.join(base, text)
        try:
            with open(path) as f:
                numbers = [float(v) for v in f.read().replace(",", " ").split()]
        except (OSError, ValueError):
            raise ValueError(f"{what}: {text!r} is neither 16 numbers nor a readable file")
    if len(numbers) != 16:
        raise ValueError(f"{what} needs 16 numbers (row-major 4x4), got {len(numbers)}")
    return np.array(numbers, dtype=np.float64).reshape(4, 4)


def read_manifest(path) -> List[dict]:
    """The rows of a manifest CSV (``id,source,target[,gt][,init]``, as ``mlsreg eval`` reads it)
    as dicts with keys id, source, target (paths resolved against the CSV's folder), gt and init
    (4x4 arrays or None). Lines that are empty or start with ``#`` are skipped."""
    path = os.fspath(path)
    base = os.path.dirname(os.path.abspath(path))
    with open(path, newline="") as f:
        lines = [line for line in f.read().splitlines() if line.strip() and line[0] != "#"]
    if not lines:
        raise ValueError(f"{path}: the manifest is empty (no header)")
    reader = csv.reader(io.StringIO("\n".join(lines)))
    header = next(reader)
    for required in ("id", "source", "target"):
        if required not in header:
            raise ValueError(f"{path}: the manifest header lacks the column {required!r}")
    rows = []
    for number, fields in enumerate(reader, start=2):
        if len(fields) != len(header):
            raise ValueError(f"{path}: manifest row {number} has {len(fields)} fields; the "
                             f"header has {len(header)}")
        row = dict(zip(header, fields))
        out = {"id": row["id"]}
        for name in ("source", "target"):
            out[name] = row[name] if os.path.isabs(row[name]) else os.path.join(base, row[name])
        for name in ("gt", "init"):
            text = row.get(name, "")
            out[name] = _parse_transform(text, f"{path} row {number} column {name}", base) \
                if text.strip() else None
        rows.append(out)
    return rows


def _is_path(value) -> bool:
    return isinstance(value, (str, os.PathLike))


def _content_key(value) -> str:
    """A hash of what a Target is built from: points (and normals, intrinsics of a Cloud)."""
    h = hashlib.blake2b(digest_size=20)

    def add(array):
        a = np.ascontiguousarray(array)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.data.cast("B") if a.size else b"")

    if isinstance(value, Cloud):
        add(value.points)
        h.update(b"normals")
        if value.normals is not None:
            add(value.normals)
        h.update(json.dumps(value.intrinsics, sort_keys=True, default=str).encode())
    else:
        add(np.asarray(value))
    return "sha:" + h.hexdigest()


def _file_key(path: str) -> str:
    """A file's identity on this machine; raises as read_cloud would when it cannot be read."""
    try:
        st = os.stat(path)
    except OSError:
        read_cloud(path)  # raises the reader's own error, which names the path
        raise
    return f"file:{path}@{st.st_mtime_ns}:{st.st_size}"


def _jobs(pairs) -> List[_Job]:
    if _is_path(pairs):
        pairs = read_manifest(pairs)
    jobs = []
    for index, row in enumerate(pairs):
        job = _Job(index=index, id=None, source=None, target=None, init=None, gt=None)
        try:
            if isinstance(row, dict):
                unknown = set(row) - {"id", "source", "target", "init", "gt"}
                if unknown:
                    raise ValueError(f"unknown keys {sorted(unknown)}")
                job.id = None if row.get("id") is None else str(row["id"])
                source, target = row["source"], row["target"]
                init, gt = row.get("init"), row.get("gt")
            else:
                row = tuple(row)
                if not 2 <= len(row) <= 4:
                    raise ValueError(f"a pair is (source, target[, init[, gt]]), not "
                                     f"{len(row)} values")
                source, target, init, gt = row + (None,) * (4 - len(row))
            job.source = os.path.abspath(os.fspath(source)) if _is_path(source) else source
            if _is_path(target):
                job.target = os.path.abspath(os.fspath(target))
                job.route_key = "file:" + job.target
            else:
                if not isinstance(target, Cloud):
                    target = np.asarray(target)
                job.target = target
                job.target_key = job.route_key = _content_key(target)
            job.init = _matrix(init)
            job.gt = _matrix(gt)
        except Exception as e:  # reported in the pair's row
            job.error = f"{type(e).__name__}: {e}"
        jobs.append(job)
    return jobs


# ---- the worker's target cache

class _TargetCache:
    """Built Targets by key, least recently used first out beyond ``max_bytes`` (the most recent
    one is kept even when alone it is larger). Threads of one worker share it; a target being
    built by one thread is waited for, not built again."""

    def __init__(self):
        self._lock = threading.Lock()
        self._entries: "collections.OrderedDict[str, Tuple[Target, int]]" = \
            collections.OrderedDict()
        self._building: Dict[str, threading.Event] = {}
        self._bytes = 0
        self.builds: Dict[str, int] = collections.Counter()
        self.failed_builds = 0
        self.hits = 0
        self.evictions = 0
        self.build_seconds = 0.0

    def _evict(self, max_bytes: int) -> None:
        while self._bytes > max_bytes and len(self._entries) > 1:
            _, (_, size) = self._entries.popitem(last=False)
            self._bytes -= size
            self.evictions += 1

    def get(self, key: str, build: Callable[[], Target], max_bytes: int) -> Tuple[Target, bool]:
        while True:
            with self._lock:
                entry = self._entries.get(key)
                if entry is not None:
                    self._entries.move_to_end(key)
                    self.hits += 1
                    self._evict(max_bytes)
                    return entry[0], False
                event = self._building.get(key)
                if event is None:
                    event = self._building[key] = threading.Event()
                    break
            event.wait()  # another thread builds it; then look again (it may have failed)
        start = time.perf_counter()
        try:
            target = build()
        except BaseException:
            with self._lock:
                self.failed_builds += 1
                del self._building[key]
            event.set()
            raise
        size = _target_bytes(target)
        with self._lock:
            self.builds[key] += 1
            self.build_seconds += time.perf_counter() - start
            self._entries[key] = (target, size)
            self._bytes += size
            self._evict(max_bytes)
            del self._building[key]
        event.set()
        return target, True

    def stats(self) -> dict:
        with self._lock:
            return {"builds": sum(self.builds.values()), "builds_by_target": dict(self.builds),
                    "failed_builds": self.failed_builds, "hits": self.hits,
                    "evictions": self.evictions, "cached_targets": len(self._entries),
                    "cached_bytes": self._bytes, "build_seconds": self.build_seconds}


def _target_bytes(target) -> int:
    size = getattr(target, "memory_bytes", None)
    if size is None:
        size = _BYTES_PER_POINT * int(getattr(target, "size", 0))
    return int(size)


_caches: Dict[Optional[str], _TargetCache] = {}
_caches_lock = threading.Lock()


def _address(dask_worker=None) -> Optional[str]:
    if dask_worker is not None:
        return dask_worker.address
    try:
        from distributed import get_worker
        return get_worker().address
    except (ImportError, ValueError):
        return None


def _cache_of(address: Optional[str]) -> _TargetCache:
    with _caches_lock:
        cache = _caches.get(address)
        if cache is None:
            cache = _caches[address] = _TargetCache()
        return cache


def worker_stats(dask_worker=None) -> dict:
    """This worker's target cache: ``builds`` (Targets built), ``builds_by_target`` (key ->
    count), ``failed_builds``, ``hits``, ``evictions``, ``cached_targets``, ``cached_bytes``,
    ``build_seconds``. On a cluster: ``client.run(mlsreg.dask.worker_stats)``."""
    return _cache_of(_address(dask_worker)).stats()


def build_count(dask_worker=None) -> int:
    """Targets this worker has built (``client.run(mlsreg.dask.build_count)``: per worker)."""
    return worker_stats(dask_worker)["builds"]


def clear_cache(dask_worker=None) -> None:
    """Drops this worker's cached targets and zeroes its counts
    (``client.run(mlsreg.dask.clear_cache)``)."""
    with _caches_lock:
        _caches.pop(_address(dask_worker), None)


# ---- one pair

def _run_pair(job: _Job, method: str, params: dict, cache_bytes: int, threads: int,
              target_data=None, cache: Optional[_TargetCache] = None,
              worker: Optional[str] = "auto") -> PairResult:
    """Registers one pair; never raises for the pair's own failures (they are its row's error)."""
    start = time.perf_counter()
    if worker == "auto":
        worker = _address()
    row = PairResult(index=job.index, id=job.id, worker=worker)
    try:
        if cache is None:
            cache = _cache_of(worker)
        source = read_cloud(job.source) if isinstance(job.source, str) else job.source
        if isinstance(job.target, str):
            key = _file_key(job.target)
            make = lambda: Target(read_cloud(job.target), threads=threads)  # noqa: E731
        else:
            key = job.target_key
            data = job.target if target_data is None else target_data
            make = lambda: Target(data, threads=threads)  # noqa: E731
        row.target_key = key
        target, row.target_built = cache.get(key, make, cache_bytes)
        result = register(source, target, method, job.init, threads=threads, **params)
        row.transform = result.transform
        row.termination = result.termination
        row.iterations = result.iterations
        if result.verification is not None:
            row.verified = bool(result.verification["verified"])
            row.verdict = result.verification.get("verdict")
        if job.gt is not None:
            error = evaluate(result, job.gt, source=source)
            row.rotation_error_deg = error.rotation_deg
            row.translation_error_d = error.translation_d
            row.rmse_d = error.rmse_d
            row.success = error.success
    except Exception as e:  # the pair's failure is its row's data
        row.error = f"{type(e).__name__}: {e}"
    row.seconds = time.perf_counter() - start
    return row


def _hold(data):
    """A task that holds an array target's data on the cluster (recomputable, unlike scatter)."""
    return data


# ---- routing

def _weight(worker: str, key: str) -> bytes:
    return hashlib.blake2b(f"{worker}\0{key}".encode(), digest_size=8).digest()


def _route(jobs: List[_Job], workers: Sequence[str]) -> Dict[int, Optional[str]]:
    """job index -> worker address. Each target's jobs (split into shards of at most one fair
    share when there are more) go to the first worker in the shard's rendezvous order whose load
    stays within 1.25 fair shares; when none has room, to the least loaded."""
    workers = sorted(workers)
    if not workers:
        return {job.index: None for job in jobs}
    groups: Dict[str, List[int]] = collections.OrderedDict()
    for job in jobs:
        groups.setdefault(job.route_key, []).append(job.index)
    total = sum(len(v) for v in groups.values())
    share = total / len(workers)
    shard_size = max(1, math.ceil(share))
    units = []
    for key, indices in groups.items():
        for s in range(0, len(indices), shard_size):
            units.append((key if s == 0 else f"{key}#{s // shard_size}",
                          indices[s:s + shard_size]))
    cap = max(_LOAD_FACTOR * share, max(len(u[1]) for u in units))
    units.sort(key=lambda u: (-len(u[1]), u[0]))  # biggest first, then a stable order
    load = dict.fromkeys(workers, 0)
    route = {}
    for key, indices in units:
        order = sorted(workers, key=lambda w: _weight(w, key), reverse=True)
        chosen = next((w for w in order if load[w] + len(indices) <= cap), None)
        if chosen is None:
            chosen = min(order, key=lambda w: load[w])  # min keeps the rendezvous order on ties
        load[chosen] += len(indices)
        for i in indices:
            route[i] = chosen
    return route


# ---- the batch

def _default_client():
    try:
        from distributed import get_client
    except ImportError:
        return None
    try:
        return get_client()
    except ValueError:  # no client
        return None


def register_many(pairs, client=None, method: str = "auto",
                  progress: Optional[Callable[[int, int], Any]] = None,
                  cache_bytes: int = DEFAULT_CACHE_BYTES, threads: int = 1,
                  **params) -> List[PairResult]:
    """Registers every pair (source -> target) and returns one PairResult per pair, in input
    order.

    ``pairs``: a manifest path or a sequence of ``(source, target[, init[, gt]])`` rows or dicts
    (keys source, target, init, gt, id); see the module's documentation. ``client``: a
    ``distributed.Client``; None uses ``distributed.get_client()`` when there is one and runs the
    pairs in this process otherwise; False always runs them here. ``method`` and ``params`` are
    mlsreg.register's (the same for every pair). ``progress(done, total)`` is called as pairs
    finish; returning False cancels the pairs not yet finished (their rows say
    ``error="cancelled"``). ``cache_bytes`` bounds each worker's cache of built targets.
    ``threads`` are the threads of each registration and target build (1: one per Dask thread).
    A pair's failure is reported in its row and never stops the others."""
    jobs = _jobs(pairs)
    if client is None:
        client = _default_client()
    rows: List[Optional[PairResult]] = [None] * len(jobs)
    for job in jobs:
        if job.error is not None:
            rows[job.index] = PairResult(index=job.index, id=job.id, error=job.error)
    runnable = [job for job in jobs if job.error is None]
    total = len(jobs)
    done = 0
    cancelled = False

    def report() -> bool:
        nonlocal done
        done += 1
        return progress is None or progress(done, total) is not False

    for row in rows:
        if row is not None and not report():
            cancelled = True
            break

    if not cancelled and client is not None and client is not False:
        _run_on_cluster(client, runnable, rows, method, params, cache_bytes, threads, report)
    elif not cancelled:
        cache = _TargetCache()
        # Grouped by target (first appearance), so that a small cache is enough.
        first = _first(runnable)
        for job in sorted(runnable, key=lambda j: (first[j.route_key], j.index)):
            rows[job.index] = _run_pair(job, method, params, cache_bytes, threads, cache=cache,
                                        worker=None)
            if not report():
                break
    return [row if row is not None else
            PairResult(index=i, id=jobs[i].id, error="cancelled") for i, row in enumerate(rows)]


def _first(jobs: List[_Job]) -> Dict[str, int]:
    first: Dict[str, int] = {}
    for n, job in enumerate(jobs):
        first.setdefault(job.route_key, n)
    return first


def _future_row(future, job: _Job) -> PairResult:
    if future.status == "finished":
        try:
            return future.result()
        except Exception as e:  # e.g. the result could not be deserialised
            return PairResult(index=job.index, id=job.id, error=f"{type(e).__name__}: {e}")
    if future.status == "cancelled":
        return PairResult(index=job.index, id=job.id, error="cancelled")
    error = future.exception()  # KilledWorker, a lost dependency, ...
    return PairResult(index=job.index, id=job.id, error=f"{type(error).__name__}: {error}")


def _run_on_cluster(client, jobs: List[_Job], rows: list, method: str, params: dict,
                    cache_bytes: int, threads: int, report: Callable[[], bool]) -> None:
    from distributed import as_completed

    if not jobs:
        return
    try:
        workers = list(client.scheduler_info().get("workers", {}))
    except Exception:  # no answer: let the scheduler place the pairs
        workers = []
    route = _route(jobs, workers)
    first = _first(jobs)
    batch = uuid.uuid4().hex[:12]
    data: Dict[str, Any] = {}  # array targets: one held copy per content
    futures = {}
    try:
        # Submitted grouped by target: each worker runs one target's pairs one after another.
        for job in sorted(jobs, key=lambda j: (route[j.index] or "", first[j.route_key],
                                               j.index)):
            where = dict(workers=[route[job.index]], allow_other_workers=True) \
                if route[job.index] else {}
            target_data = None
            if not isinstance(job.target, str):
                target_data = data.get(job.target_key)
                if target_data is None:
                    target_data = data[job.target_key] = client.submit(
                        _hold, job.target, key=f"mlsreg-target-{job.target_key[4:]}", **where)
                job = dataclasses.replace(job, target=None)  # the array travels once, as data
            future = client.submit(_run_pair, job, method, params, cache_bytes, threads,
                                   target_data, key=f"mlsreg-pair-{batch}-{job.index}", **where)
            futures[future.key] = (future, job)
        for future in as_completed([f for f, _ in futures.values()]):
            job = futures.pop(future.key)[1]
            rows[job.index] = _future_row(future, job)
            future.release()
            if not report():
                break
    finally:
        pending = [f for f, _ in futures.values()]
        if pending:
            client.cancel(pending)
