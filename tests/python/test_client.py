"""The Python client against a real server on 127.0.0.1: targets, a served registration equal to
the local one, the progress stream, cancellation, batches and errors."""

import numpy as np
import pytest

import mlsreg


@pytest.fixture(scope="module")
def client(server, bun045):
    c = mlsreg.Client(server)
    info = c.upload_target("bun045", bun045)
    assert info["id"] == "bun045" and info["point_count"] == len(bun045)
    return c


def test_targets_are_uploaded_listed_and_deleted(client, bun000):
    assert client.health() == "SERVING"
    assert client.get_target("bun045")["state"] == "ready"
    assert client.get_target("bun045")["digest"].startswith("sha256:")
    client.upload_target("scratch", bun000.points[:2000])
    assert {t["id"] for t in client.list_targets()} >= {"bun045", "scratch"}
    client.delete_target("scratch")
    with pytest.raises(LookupError, match="scratch"):
        client.get_target("scratch")
    stats = client.stats()
    assert isinstance(stats, dict) and stats


def test_a_served_registration_equals_the_local_one(client, bun000, bunny_target, gt,
                                                    near_start):
    remote = client.register("bun045", bun000, init=near_start, gt=gt)
    local = mlsreg.register(bun000, bunny_target, init=near_start)
    np.testing.assert_allclose(remote.transform, local.transform, atol=1e-9)
    assert remote.iterations == local.iterations and remote.verified
    assert remote.request_id and remote.attempts == 1
    assert remote.ground_truth_error.success and remote.ground_truth_error.rmse_d < 1.0
    assert mlsreg.evaluate(remote, gt).rmse_d == pytest.approx(
        remote.ground_truth_error.rmse_d, rel=1e-6)


def test_the_progress_stream_yields_reports_then_the_result(client, bun000, near_start):
    stream = client.stream("bun045", bun000, method="mls-sicp", init=near_start)
    reports = list(stream)
    result = stream.result(timeout=60)
    assert reports and all(isinstance(r, mlsreg.IterationReport) for r in reports)
    iterations = [r.iteration for r in reports]
    assert iterations == sorted(iterations) and iterations[-1] == result.iterations


def test_a_callback_returning_false_cancels_the_served_registration(client, bun000, near_start):
    seen = []

    def callback(report):
        seen.append(report.iteration)
        return False

    with pytest.raises(mlsreg.Error) as raised:
        client.register("bun045", bun000, method="mls-sicp", init=near_start, callback=callback,
                        max_iterations=100000, convergence_d=0, stall_d=0,
                        stall_noise_fraction=0, stall_standard_errors=0)
    assert raised.value.code == "CANCELLED"
    assert seen and seen[0] == 1
    # The server keeps serving.
    assert client.register("bun045", bun000, method="cp-sicp", init=near_start).iterations > 0


def test_a_batch_reports_each_job(client, bun000, near_start):
    jobs = [
        {"target_id": "bun045", "source": bun000, "init": near_start, "method": "cp-sicp"},
        {"target_id": "missing", "source": bun000},
        {"target_id": "bun045", "source": bun000, "init": near_start, "max_iterations": 2},
    ]
    outcomes = client.register_batch(jobs, concurrency=2)
    assert [o.ok for o in outcomes] == [True, False, True]
    assert isinstance(outcomes[1].error, LookupError) and "missing" in str(outcomes[1].error)
    # max_iterations caps each phase of auto: the coarse alignment, the refinement and the finish.
    assert outcomes[2].result.iterations <= 6


def test_bad_requests_raise_value_error(client, bun000):
    with pytest.raises(ValueError, match=r"source.points\[3\]: non-finite"):
        client.register("bun045", np.where(np.arange(100)[:, None] == 3, np.nan,
                                           bun000.points[:100]))
    with pytest.raises(ValueError, match="max_iterations"):
        client.register("bun045", bun000, max_iterations=-1)
    with pytest.raises(ValueError, match="target_id"):
        client.upload_target("bad id!", bun000.points[:100])
