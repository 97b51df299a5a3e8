"""mlsreg.dask.register_many on a real 2-process Dask cluster (LocalCluster): the same transforms
as in-process, each target built once per worker, a worker killed mid-batch, failed pairs in
their own rows, input order, progress and cancellation."""

import os
import signal
import subprocess
import sys

import numpy as np
import pytest

import mlsreg
from conftest import BUNNY

distributed = pytest.importorskip("distributed")
import mlsreg.dask as md  # noqa: E402

PAIRS = BUNNY / "pairs.csv"
IDS = ["bun000_bun045", "bun315_bun000"]  # the manifest's order


def start_cluster():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       dashboard_address=":0", host="127.0.0.1")
    return cluster, distributed.Client(cluster)


@pytest.fixture(scope="module")
def cluster():
    cluster, client = start_cluster()
    try:
        yield cluster, client
    finally:
        client.close()
        cluster.close()


@pytest.fixture(scope="module")
def reference():
    """Each manifest pair registered in this process: mlsreg.register(source, Target(target))."""
    transforms = []
    for row in md.read_manifest(PAIRS):
        target = mlsreg.Target(mlsreg.read_cloud(row["target"]))
        transforms.append(mlsreg.register(mlsreg.read_cloud(row["source"]), target, "auto",
                                          row["init"], threads=1).transform)
    return transforms


def test_import_mlsreg_does_not_import_dask():
    code = ("import sys, mlsreg\n"
            "assert 'distributed' not in sys.modules and 'dask' not in sys.modules\n"
            "assert 'dask' in dir(mlsreg)\n"
            "m = mlsreg.dask\n"
            "assert m.__name__ == 'mlsreg.dask' and 'distributed' not in sys.modules\n")
    subprocess.run([sys.executable, "-c", code], check=True, env=os.environ.copy())


def test_the_manifest_gives_ids_paths_and_ground_truth():
    rows = md.read_manifest(PAIRS)
    assert [r["id"] for r in rows] == IDS
    assert rows[0]["source"] == str(BUNNY / "bun000.ply") and rows[0]["init"] is None
    assert rows[0]["gt"].shape == (4, 4) and rows[0]["gt"][3, 3] == 1.0


def test_local_run_without_a_client_matches_register(reference):
    rows = md.register_many(PAIRS, client=False)
    assert [r.id for r in rows] == IDS and [r.index for r in rows] == [0, 1]
    for row, transform in zip(rows, reference):
        assert row.error is None and row.worker is None
        assert np.array_equal(row.transform, transform)


def test_the_cluster_gives_the_local_transforms_in_input_order(cluster, reference):
    _, client = cluster
    workers = set(client.scheduler_info()["workers"])
    rows = md.register_many(str(PAIRS))  # client=None: the default client (this cluster's)
    assert [r.id for r in rows] == IDS and [r.index for r in rows] == [0, 1]
    for row, transform in zip(rows, reference):
        assert row.error is None, row.error
        assert row.worker in workers
        assert np.array_equal(row.transform, transform)
        assert row.verified and row.verdict == "verified" and row.termination == "converged"
        assert row.success and row.rotation_error_deg < 1.0 and row.translation_error_d < 1.0
        assert row.iterations > 0 and row.seconds > 0


def test_each_target_is_built_once_per_worker(cluster, reference):
    _, client = cluster
    client.run(md.clear_cache)
    pairs = md.read_manifest(PAIRS) * 3
    rows = md.register_many(pairs, client=client)
    assert [r.index for r in rows] == list(range(6))
    for row in rows:
        assert row.error is None, row.error
        assert np.array_equal(row.transform, reference[row.index % 2])
    stats = client.run(md.worker_stats)
    assert set(stats) == set(client.scheduler_info()["workers"])
    built = {}
    for address, s in stats.items():
        assert all(n == 1 for n in s["builds_by_target"].values()), (address, s)
        assert s["failed_builds"] == 0
        for key in s["builds_by_target"]:
            built.setdefault(key, []).append(address)
    assert sorted(k.split("@")[0] for k in built) == [
        "file:" + str(BUNNY / "bun000.ply"), "file:" + str(BUNNY / "bun045.ply")]
    assert sum(s["builds"] for s in stats.values()) == sum(r.target_built for r in rows)
    assert sum(s["builds"] + s["hits"] for s in stats.values()) == len(rows)
    assert client.run(md.build_count) == {a: s["builds"] for a, s in stats.items()}


def test_a_failed_pair_reports_its_error_in_its_own_row(cluster, reference, bun000, bun045,
                                                        tmp_path):
    _, client = cluster
    good = md.read_manifest(PAIRS)
    pairs = [
        good[0],
        (tmp_path / "nope.ply", BUNNY / "bun045.ply"),  # no source
        good[1],
        {"id": "no-target", "source": BUNNY / "bun000.ply", "target": tmp_path / "gone.ply"},
        (bun000.points, bun045.points, None, good[0]["gt"]),  # arrays: a content-hashed target
        (bun000,),
    ]
    rows = md.register_many(pairs, client=client)
    assert [r.index for r in rows] == list(range(6))
    assert rows[1].error.startswith("FileNotFoundError") and "nope.ply" in rows[1].error
    assert rows[3].error.startswith("FileNotFoundError") and "gone.ply" in rows[3].error
    assert rows[3].id == "no-target" and rows[3].transform is None
    assert rows[5].error == "ValueError: a pair is (source, target[, init[, gt]]), not 1 values"
    for i, transform in [(0, reference[0]), (2, reference[1]), (4, reference[0])]:
        assert rows[i].error is None, rows[i].error
        assert np.array_equal(rows[i].transform, transform)
    assert rows[4].target_key.startswith("sha:") and rows[4].success


def test_progress_counts_and_false_cancels_the_rest(cluster):
    _, client = cluster
    calls = []

    def progress(done, total):
        calls.append((done, total))
        return False

    pairs = md.read_manifest(PAIRS) * 2
    rows = md.register_many(pairs, client=client, progress=progress)
    assert calls == [(1, 4)] and len(rows) == 4
    assert sum(r.error is None for r in rows) == 1
    assert sum(r.error == "cancelled" for r in rows) == 3
    local = md.register_many(pairs, client=False, progress=progress)
    assert [r.error for r in local] == [None, "cancelled", "cancelled", "cancelled"]


def test_a_worker_killed_mid_batch_still_completes_every_pair(reference):
    cluster, client = start_cluster()
    try:
        pids = client.run(os.getpid)
        killed = {}

        def progress(done, total):
            if not killed:  # the first result: kill a worker that still has pairs to run
                processing = client.processing()
                victim = max(processing, key=lambda a: len(processing[a]))
                killed["address"] = victim
                killed["pending"] = {int(k.rsplit("-", 1)[1]) for k in processing[victim]}
                os.kill(pids[victim], signal.SIGKILL)

        pairs = md.read_manifest(PAIRS) * 4
        rows = md.register_many(pairs, client=client, progress=progress)
        assert killed["pending"], "the killed worker had nothing left to run"
        for row in rows:
            assert row.error is None, row.error
            assert np.array_equal(row.transform, reference[row.index % 2])
        for i in killed["pending"]:
            assert rows[i].worker != killed["address"]
    finally:
        client.close()
        cluster.close()
