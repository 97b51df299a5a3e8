"""mlsreg: rigid registration of overlapping 3-D scans with MLS correspondences in Sparse ICP.

Local registration::

    import mlsreg, numpy as np
    source = mlsreg.read_cloud("bun000.ply")
    target = mlsreg.Target(mlsreg.read_cloud("bun045.ply").points)   # built once, reused
    result = mlsreg.register(source, target, init=np.eye(4))          # method "auto"
    result.transform                                                  # 4x4 ndarray

Clouds are NumPy arrays of shape (N, 3) or (N, 6) (points and normals), an mlsreg.Cloud, or an
Open3D point cloud (``open3d.geometry.PointCloud`` or ``open3d.t.geometry.PointCloud``).
Registration parameters are keyword arguments named as in the library's parameter table
(``mlsreg.parameters()``: its names, such as ``min_normal_dot``, or the CLI's flags with ``_``
for ``-``, such as ``tau_n``), with its defaults and ranges.

Remote registration goes through ``mlsreg.Client`` (the C++ client library: retries, replica
routing, chunked uploads).

Batches on a Dask cluster: ``mlsreg.dask.register_many(pairs, client)`` (each target built once
per worker; Dask is imported only there).

Errors: bad input raises ValueError with the library's message; a missing file
FileNotFoundError; an unknown target LookupError; everything else mlsreg.Error (``.code`` is the
status code's name).
"""

from __future__ import annotations

import dataclasses
import json
import queue
import threading
import warnings
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Callable, Iterator, Optional, Sequence, Union

import numpy as np

from . import _mlsreg
from ._mlsreg import Error, Target, methods, parameters, read_poses

__all__ = [
    "Cloud", "Target", "IterationReport", "Result", "PoseError", "BatchOutcome", "Client",
    "RegistrationStream", "Error", "read_cloud", "write_cloud", "register", "evaluate", "methods",
    "parameters",
    "TRACE_DTYPE", "AlignResult", "align_scans", "merge_scans", "read_poses",
]

__version__ = "0.1.0"

# A length: a number in units of d (the target's mean sampling distance) or a str with a unit,
# as the CLI's flags take them ("20", "20d", "5m", "30cm", "5mm").
Length = Union[float, str]


def __dir__():
    """The package's API only (not the modules it imports, such as numpy and json)."""
    return sorted(__all__ + ["__version__", "dask"])


def __getattr__(name: str):
    """``mlsreg.dask`` (batches on a Dask cluster) is imported on first use, and it imports Dask
    only when it runs on a cluster: ``import mlsreg`` works without Dask installed."""
    if name == "dask":
        import importlib
        return importlib.import_module(".dask", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


@dataclasses.dataclass
class Cloud:
    """A scan read from a file: points (N, 3) float64, normals (N, 3) or None, colors (N, 3)
    uint8 or None, and metadata. ``notes`` say how the file's fields were read (fields ignored,
    unnamed columns read from the data). Registration uses the points only: normals are
    estimated from them, and the colours are carried to files written with write_cloud."""

    points: np.ndarray
    normals: Optional[np.ndarray] = None
    colors: Optional[np.ndarray] = None
    viewpoint: Optional[np.ndarray] = None  # the sensor origin, when the file says
    intrinsics: Optional[dict] = None  # pinhole camera of an organised scan
    path: Optional[str] = None
    notes: list = dataclasses.field(default_factory=list)

    @property
    def array(self) -> np.ndarray:
        """(N, 6) points and normals when there are normals, else (N, 3) points."""
        if self.normals is None:
            return self.points
        return np.hstack([self.points, self.normals])

    def __len__(self) -> int:
        return len(self.points)

    def __array__(self, dtype=None):
        return self.array if dtype is None else self.array.astype(dtype)


def read_cloud(path: str, columns: Optional[Sequence[str]] = None) -> Cloud:
    """Reads a .ply, .pcd, .xyz/.txt/.csv or .npy cloud (with normals, colours and metadata if
    present). ``columns`` names the columns of a text or .npy file (e.g. ``["x", "y", "z", "r",
    "g", "b"]``; other names are read and ignored); by default a text file's header line or the
    column count decides. Each of the cloud's ``notes`` is also issued as a UserWarning."""
    cloud = Cloud(path=str(path), **_mlsreg.read_cloud(str(path), list(columns or [])))
    for note in cloud.notes:
        warnings.warn(note, stacklevel=2)
    return cloud


def write_cloud(path: str, cloud) -> None:
    """Writes a cloud (as register takes it: an array, a Cloud, an Open3D cloud) with its normals
    and colours in the format the extension names: .ply, .pcd, .xyz/.txt/.csv (a header line
    names the columns when there are more than x y z) or .npy (points and normals only)."""
    _mlsreg.write_cloud(str(path), cloud)


@dataclasses.dataclass
class IterationReport:
    """One ICP iteration, as the progress callback and stream see it."""

    iteration: int
    # "single", or for method auto "coarse", "start", "global", "candidate", "final", "finish",
    # "rival"
    stage: str
    candidate: int  # auto: the candidate refined, else -1
    rmse: float  # of this iteration's accepted correspondences, absolute units
    rmse_d: float  # the same in units of the target's sampling distance d
    matched: int
    rejected_normal: int
    rejected_curvature: int
    rejected_distance: int
    invalid: int
    admm_iterations: int
    elapsed_seconds: float
    transform: np.ndarray = dataclasses.field(repr=False)


TRACE_DTYPE = np.dtype([
    ("iteration", np.int32), ("stage", "U9"), ("candidate", np.int32), ("rmse", np.float64),
    ("rmse_d", np.float64), ("matched", np.int32), ("rejected_normal", np.int32),
    ("rejected_curvature", np.int32), ("rejected_distance", np.int32), ("invalid", np.int32),
    ("admm_iterations", np.int32), ("elapsed_seconds", np.float64),
])


def _trace_array(rows: Sequence[dict]) -> np.ndarray:
    names = TRACE_DTYPE.names
    return np.array([tuple(row[n] for n in names) for row in rows], dtype=TRACE_DTYPE)


@dataclasses.dataclass
class PoseError:
    """A transform against ground truth (paper Eq. 10): RMSE over the source in units of d."""

    rmse_d: float
    success: bool  # rmse_d below the threshold (5 d by default)
    rotation_deg: float
    translation_d: float


@dataclasses.dataclass
class Result:
    """A registration's result. ``trace`` is a structured array (TRACE_DTYPE), one row per
    iteration; ``verification`` says whether it can be trusted (verdict and evidence, any method);
    ``scales`` the lengths chosen from the data; ``auto`` is method auto's report (candidates,
    stage times)."""

    transform: np.ndarray
    converged: bool
    termination: str  # "converged", "max_iterations", "cancelled", "too_few_correspondences"
    iterations: int
    trace: np.ndarray
    timings: dict
    sampling_distance: float
    num_samples: int
    mls_radius_d: float
    mls_radius_auto: bool
    target_noise_d: float
    source_noise_d: float
    auto: Optional[dict]
    method: str
    verification: Optional[dict] = None
    # Another pose that explains the source as well (verdict "ambiguous"): a candidate dict.
    rival: Optional[dict] = None
    scales: Optional[dict] = None
    # Remote registrations only:
    request_id: Optional[str] = None
    queue_seconds: Optional[float] = None
    attempts: Optional[int] = None
    ground_truth_error: Optional[PoseError] = None
    source: Optional[Any] = dataclasses.field(default=None, repr=False)

    @property
    def verified(self) -> Optional[bool]:
        """Whether the result verified against the target (None when verify=False)."""
        return None if self.verification is None else bool(self.verification["verified"])

    def __repr__(self) -> str:
        last = f", rmse_d={self.trace['rmse_d'][-1]:.4g}" if len(self.trace) else ""
        verified = "" if self.verified is None else f", verified={self.verified}"
        return (f"Result(method={self.method!r}, termination={self.termination!r}, "
                f"iterations={self.iterations}{last}{verified}, "
                f"seconds={self.timings.get('total', 0.0):.3g})")


def _result(raw: dict, method: str, source) -> Result:
    raw = dict(raw)
    raw["trace"] = _trace_array(raw["trace"])
    gt = raw.pop("ground_truth_error", None)
    fields = {f.name for f in dataclasses.fields(Result)}
    result = Result(method=method, source=source,
                    ground_truth_error=PoseError(**gt) if gt else None,
                    **{k: v for k, v in raw.items() if k in fields})
    return result


def _adapt(callback: Optional[Callable[[IterationReport], Any]]):
    if callback is None:
        return None
    return lambda report: callback(IterationReport(**report))


def register(source, target, method: str = "auto", init=None,
             callback: Optional[Callable[[IterationReport], Any]] = None, threads: int = 1,
             **params) -> Result:
    """Registers ``source`` to ``target`` (source -> target, rigid) from ``init`` (4x4, default
    identity).

    ``source`` and ``target`` are (N, 3) or (N, 6) arrays, Clouds or Open3D point clouds; pass a
    ``Target`` to reuse a target's prepared surface. ``callback(report)`` is called after every
    iteration; returning False cancels (the result then says ``termination == "cancelled"``).
    ``params`` are the parameter table's names or the CLI's flags with ``_`` for ``-``
    (``mlsreg.parameters()``: ``min_normal_dot=0.5`` or ``tau_n=0.5``); None means auto.
    ``threads`` (1 to 256) are used inside the registration and the target build; the result
    does not depend on them. The GIL is released while registering.
    """
    raw = _mlsreg._register(source, target, method, init, _adapt(callback), threads, params)
    return _result(raw, method, source)


def evaluate(result: Result, gt, source=None, success_threshold_d: float = 5.0) -> PoseError:
    """The result's error against the ground-truth transform ``gt``, over the source's points
    (the registered source unless given) in units of the target's d."""
    source = result.source if source is None else source
    if source is None:
        raise ValueError("source: the result does not hold its source; pass source=")
    return PoseError(**_mlsreg._evaluate(source, result.transform, gt, result.sampling_distance,
                                         success_threshold_d))


@dataclasses.dataclass
class AlignResult:
    """Many scans in one frame: ``poses[i]`` maps scan i into the anchor's frame (4x4), with
    ``pose_covariances[i]`` its 6x6 covariance (rotation vector, translation of the scan's
    origin, in the anchor's frame) or None (the anchor; none computed);
    ``edges`` are the pairwise registrations (dicts: from, to, relative, overlap,
    residual_before_d, residual_after_d, trusted, kept, ...)."""

    poses: list
    chained_poses: list
    pose_covariances: list
    edges: list
    chain_deviation_d: list
    loop_closure_rotation_deg: float
    loop_closure_error_d: float
    loop_closure_exceeded: bool
    unverified_scans: list
    sampling_distance: float
    graph_iterations: int
    covariance_weighted_edges: int
    seconds: float


def align_scans(scans: Sequence, poses=None, pairs: str = "loop", method: str = "auto",
                min_overlap: float = 0.3, overlap_distance_d: Length = 20.0, anchor: int = 0,
                threads: int = 1, callback: Optional[Callable[[dict, int, int], Any]] = None,
                **params) -> AlignResult:
    """Aligns many scans into the frame of scan ``anchor``: pairwise registrations
    (``method``, auto by default as in the CLI, with ``params`` from the parameter table) along
    ``pairs`` ("sequential", "loop" or "overlap"), then a pose graph that drops edges that
    disagree. ``poses`` are initial poses (scan -> common frame), e.g. from ``read_poses``.
    ``overlap_distance_d``: how near a sample must lie to the other scan to count as overlap
    (``pairs="overlap"``); a number in d or a length such as ``"5m"``.
    ``callback(edge, done, total)`` runs after each edge; returning False cancels (mlsreg.Error,
    code CANCELLED). The GIL is released while aligning."""
    raw = _mlsreg._align_scans(list(scans), poses, pairs, method, min_overlap,
                               overlap_distance_d, anchor, threads, callback, params)
    return AlignResult(**raw)


def merge_scans(scans: Sequence, poses: Sequence, resample: bool = False, spacing_d: Length = 1.0,
                radius_d: Length = 0.0, d: Optional[float] = None, threads: int = 1) -> Cloud:
    """Every scan under its pose (e.g. ``align_scans(...).poses``) as one Cloud. With
    ``resample``, one point per voxel of ``spacing_d`` d projected onto the joint MLS surface of
    all scans (``radius_d`` d; 0: from the merged cloud's noise), with the surface's normals;
    ``d`` is the scans' sampling distance (``AlignResult.sampling_distance``; measured when
    None). ``spacing_d`` and ``radius_d`` are numbers in d or lengths such as ``"2cm"``. The GIL
    is released while resampling."""
    raw = _mlsreg._merge_scans(list(scans), list(poses), resample, spacing_d, radius_d, d, threads)
    return Cloud(**raw)


@dataclasses.dataclass
class BatchOutcome:
    """One job of Client.register_batch: its result, or the exception it raised."""

    job: dict
    result: Optional[Result] = None
    error: Optional[BaseException] = None

    @property
    def ok(self) -> bool:
        return self.error is None

    def __repr__(self) -> str:
        outcome = f"result={self.result!r}" if self.ok else f"error={self.error!r}"
        return f"BatchOutcome(target_id={self.job.get('target_id')!r}, {outcome})"


class RegistrationStream:
    """A served registration as an iterator of IterationReports; ``result()`` waits for the end
    and returns the Result (or raises the call's error); ``cancel()`` stops it."""

    _END = object()

    def __init__(self, run: Callable[[Callable], Result]):
        self._queue: "queue.Queue" = queue.Queue()
        self._cancelled = threading.Event()
        self._result: Optional[Result] = None
        self._error: Optional[BaseException] = None

        def on_progress(report: IterationReport):
            self._queue.put(report)
            return not self._cancelled.is_set()

        def body():
            try:
                self._result = run(on_progress)
            except BaseException as e:  # handed to the caller in result()
                self._error = e
            finally:
                self._queue.put(self._END)

        self._thread = threading.Thread(target=body, daemon=True)
        self._thread.start()

    def __iter__(self) -> Iterator[IterationReport]:
        return self

    def __next__(self) -> IterationReport:
        item = self._queue.get()
        if item is self._END:
            self._queue.put(self._END)  # later calls end too
            raise StopIteration
        return item

    def cancel(self) -> None:
        self._cancelled.set()

    def result(self, timeout: Optional[float] = None) -> Result:
        self._thread.join(timeout)
        if self._thread.is_alive():
            raise TimeoutError("the registration is still running")
        if self._error is not None:
            raise self._error
        return self._result


class Client:
    """A client of one or more mlsreg servers (``"host:port"``, ``"a:1,b:2"`` replicas, or
    ``"dns:///NAME:PORT"``), over the C++ client library: transient failures are retried with
    backoff, targets are routed to their replica and re-uploaded when a replica lost them."""

    def __init__(self, address: str = "127.0.0.1:50051", token: Optional[str] = None,
                 tls: bool = False, ca_cert: str = "", client_cert: str = "",
                 client_key: str = "", deadline_seconds: float = 600.0, max_attempts: int = 5,
                 float32: bool = False):
        self._client = _mlsreg._Client(address, token or "", tls, ca_cert, client_cert,
                                       client_key, deadline_seconds, max_attempts, float32)

    def upload_target(self, target_id: str, cloud) -> dict:
        """Uploads a cloud as target ``target_id`` (idempotent for the same content)."""
        return self._client.upload_target(target_id, cloud)

    def get_target(self, target_id: str) -> dict:
        return self._client.get_target(target_id)

    def list_targets(self) -> list:
        return self._client.list_targets()

    def delete_target(self, target_id: str) -> None:
        self._client.delete_target(target_id)

    def health(self, replica: int = 0) -> str:
        return self._client.health(replica)

    def stats(self, replica: int = 0) -> dict:
        return json.loads(self._client.stats_json(replica))

    @property
    def replicas(self) -> list:
        return self._client.replicas()

    def register(self, target_id: str, source, method: str = "auto", init=None, gt=None,
                 callback: Optional[Callable[[IterationReport], Any]] = None, **params) -> Result:
        """Registers ``source`` against the server's target ``target_id``; as mlsreg.register,
        with ``gt`` (optional) evaluated on the server."""
        raw = self._client.register(target_id, source, method, init, gt, _adapt(callback), params)
        return _result(raw, method, source)

    def align_scans(self, scans: Sequence, poses=None, pairs: str = "loop",
                    method: str = "auto", min_overlap: float = 0.3,
                    overlap_distance_d: Length = 20.0, anchor: int = 0,
                    callback: Optional[Callable[[dict, int, int], Any]] = None,
                    **params) -> AlignResult:
        """mlsreg.align_scans on the server (the AlignScans RPC): each scan is a ``str`` (the id
        of a target on the server) or a cloud sent with the call. ``callback(edge, done, total)``
        sees every edge as the server finishes it; returning False cancels (mlsreg.Error, code
        CANCELLED). The server decides the threads."""
        raw = self._client.align_scans(list(scans), poses, pairs, method, min_overlap,
                                       overlap_distance_d, anchor, callback, params)
        raw.pop("request_id")
        raw.pop("queue_seconds")
        return AlignResult(**raw)

    def stream(self, target_id: str, source, method: str = "auto", init=None, gt=None,
               **params) -> RegistrationStream:
        """A served registration as an iterator of progress reports::

            stream = client.stream("bunny", source)
            for report in stream:
                print(report.iteration, report.rmse_d)
            result = stream.result()
        """
        return RegistrationStream(lambda on_progress: self.register(
            target_id, source, method, init, gt, on_progress, **params))

    def register_batch(self, jobs: Sequence[dict], concurrency: int = 4) -> list:
        """Runs jobs concurrently, each a dict of Client.register's arguments (``target_id``,
        ``source``, and optionally ``method``, ``init``, ``gt`` and parameters). Returns one
        BatchOutcome per job, in order; a failed job holds its exception."""

        def run(job: dict) -> BatchOutcome:
            try:
                return BatchOutcome(job=job, result=self.register(**job))
            except Exception as e:  # reported per job
                return BatchOutcome(job=job, error=e)

        with ThreadPoolExecutor(max_workers=max(1, concurrency)) as pool:
            return list(pool.map(run, jobs))
