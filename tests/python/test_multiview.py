"""mlsreg.align_scans and read_poses: real bunny scans against bun.conf, cancellation and bad
input."""

import numpy as np
import pytest

import mlsreg
from conftest import SOURCE_DIR

BUNNY = SOURCE_DIR.parent / "shared" / "data" / "real" / "stanford_bunny"
NAMES = ["bun000.ply", "bun045.ply", "bun315.ply"]

pytestmark = pytest.mark.skipif(not (BUNNY / "bun.conf").exists(), reason="no bunny data")


@pytest.fixture(scope="module")
def scans():
    return [mlsreg.read_cloud(BUNNY / n) for n in NAMES]


@pytest.fixture(scope="module")
def truth():
    return mlsreg.read_poses(str(BUNNY / "bun.conf"), [str(BUNNY / n) for n in NAMES])


def rotation_deg(a, b):
    r = a[:3, :3].T @ b[:3, :3]
    return np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1)))


def test_the_bunny_ring_is_aligned_to_its_ground_truth(scans, truth):
    start = [truth[0]] + [p.copy() for p in truth[1:]]
    for p in start[1:]:
        p[:3, 3] += 0.002  # about 3.4 d off
    edges = []
    result = mlsreg.align_scans(scans, poses=start, threads=2,
                                callback=lambda e, done, total: edges.append((done, total)))
    assert isinstance(result, mlsreg.AlignResult) and len(result.poses) == 3
    assert sorted(edges) == [(1, 3), (2, 3), (3, 3)]  # loop of 3: (0,1), (1,2), (2,0)
    d = result.sampling_distance
    to0 = np.linalg.inv(truth[0])
    for pose, t in zip(result.poses, truth):
        expected = to0 @ t
        assert rotation_deg(pose, expected) < 0.5
        assert np.linalg.norm(pose[:3, 3] - expected[:3, 3]) < 2 * d
    assert all(e["kept"] for e in result.edges)
    # Each pose but the anchor's carries its covariance from the covariance-weighted graph:
    # symmetric, positive definite, and well under a degree and a d (the ring fixes every view).
    assert result.covariance_weighted_edges == 3
    assert result.pose_covariances[0] is None
    for c in result.pose_covariances[1:]:
        assert c.shape == (6, 6) and np.allclose(c, c.T)
        assert np.linalg.eigvalsh(c).min() > 0
        assert np.degrees(np.sqrt(np.linalg.eigvalsh(c[:3, :3]).max())) < 1.0
        assert np.sqrt(np.linalg.eigvalsh(c[3:, 3:]).max()) < d


def test_merge_scans_as_is_and_resampled_onto_the_joint_surface(scans, truth):
    to0 = np.linalg.inv(truth[0])
    poses = [to0 @ t for t in truth]
    merged = mlsreg.merge_scans(scans, poses)
    assert isinstance(merged, mlsreg.Cloud) and len(merged) == sum(len(s) for s in scans)
    moved = scans[1].points @ poses[1][:3, :3].T + poses[1][:3, 3]
    assert np.allclose(merged.points[len(scans[0]):len(scans[0]) + len(scans[1])], moved)
    resampled = mlsreg.merge_scans(scans, poses, resample=True, threads=2)
    # One point per voxel of d: fewer than merged, each on a unit normal, and near the scans.
    assert 0.2 * len(merged) < len(resampled) < len(merged)
    assert np.allclose(np.linalg.norm(resampled.normals, axis=1), 1.0)
    lo, hi = merged.points.min(axis=0), merged.points.max(axis=0)
    assert np.all(resampled.points >= lo - 0.005) and np.all(resampled.points <= hi + 0.005)
    with pytest.raises(ValueError, match="2 poses for 3 scans"):
        mlsreg.merge_scans(scans, poses[:2])
    with pytest.raises(ValueError, match="spacing_d"):
        mlsreg.merge_scans(scans, poses, resample=True, spacing_d=0)


def test_lengths_in_metres_are_the_same_lengths_in_d(scans, truth):
    """overlap_distance_d, spacing_d and radius_d take "…m" as the CLI's flags do."""
    to0 = np.linalg.inv(truth[0])
    poses = [to0 @ t for t in truth]
    in_d = mlsreg.align_scans(scans, poses=poses, pairs="overlap", overlap_distance_d=2,
                              max_iterations=2)
    d = in_d.sampling_distance
    in_m = mlsreg.align_scans(scans, poses=poses, pairs="overlap",
                              overlap_distance_d=f"{2 * d!r}m", max_iterations=2)
    assert len(in_d.edges) >= 2
    assert [(e["from"], e["to"]) for e in in_m.edges] == [(e["from"], e["to"]) for e in in_d.edges]
    merged_d = mlsreg.merge_scans(scans, poses, resample=True, spacing_d=3, radius_d=6, d=d)
    merged_m = mlsreg.merge_scans(scans, poses, resample=True, spacing_d=f"{3 * d * 1000!r}mm",
                                  radius_d=f"{6 * d!r} m", d=d)
    assert len(merged_m) == len(merged_d)
    assert np.abs(merged_m.points - merged_d.points).max() < 1e-9
    with pytest.raises(ValueError, match="spacing_d: '3 parsecs' is not a length"):
        mlsreg.merge_scans(scans, poses, resample=True, spacing_d="3 parsecs")
    with pytest.raises(ValueError, match="overlap_distance_d: a number"):
        mlsreg.align_scans(scans, overlap_distance_d=None)


def test_a_callback_returning_false_cancels(scans, truth):
    with pytest.raises(mlsreg.Error) as raised:
        mlsreg.align_scans(scans, poses=truth, callback=lambda e, done, total: False)
    assert raised.value.code == "CANCELLED"


def test_bad_input_raises_value_error(scans, truth):
    with pytest.raises(ValueError, match="scans: need at least 2, got 1"):
        mlsreg.align_scans(scans[:1])
    with pytest.raises(ValueError, match="initial_poses: 2 poses for 3 scans"):
        mlsreg.align_scans(scans, poses=truth[:2])
    with pytest.raises(ValueError, match="pairs"):
        mlsreg.align_scans(scans, pairs="ring")
    with pytest.raises(ValueError, match=r"scans\[1\]: dtype int64"):
        mlsreg.align_scans([scans[0].points, scans[1].points.astype(np.int64)])
    with pytest.raises(ValueError, match="max_iterations"):
        mlsreg.align_scans(scans, max_iterations=0)
    with pytest.raises(ValueError, match="no 'bmesh nope.ply' line"):
        mlsreg.read_poses(str(BUNNY / "bun.conf"), ["nope.ply"])


def test_a_served_alignment_equals_the_local_one(server, scans, truth):
    """The AlignScans RPC: one scan cached on the server (by id), two sent with the call."""
    client = mlsreg.Client(server)
    client.upload_target("bun045.ply", scans[1])
    start = [p.copy() for p in truth]
    for p in start[1:]:
        p[:3, 3] += 0.002
    local = mlsreg.align_scans(scans, poses=start)
    edges = []
    served = client.align_scans([scans[0], "bun045.ply", scans[2]], poses=start,
                                callback=lambda e, done, total: edges.append((e["from"], e["to"])))
    assert sorted(edges) == [(0, 1), (1, 2), (2, 0)]
    for a, b in zip(local.poses, served.poses):
        assert np.abs(a - b).max() < 1e-6
    assert served.pose_covariances[0] is None
    for a, b in zip(local.pose_covariances[1:], served.pose_covariances[1:]):
        assert np.abs(a - b).max() <= 1e-6 * np.abs(a).max()
    assert [e["kept"] for e in served.edges] == [e["kept"] for e in local.edges]
    with pytest.raises(mlsreg.Error) as raised:
        # Cancelled after the first of three edges (each takes a few hundred ms on the server).
        client.align_scans([scans[0], "bun045.ply", scans[2]], poses=truth,
                           callback=lambda e, done, total: False)
    assert raised.value.code == "CANCELLED"
    with pytest.raises(LookupError, match=r"header.scans\[1\].target_id: target 'nope' not found"):
        client.align_scans([scans[0], "nope"])
    with pytest.raises(ValueError, match="initial_poses: 2 poses for 3 scans"):
        client.align_scans([scans[0], "bun045.ply", scans[2]], poses=truth[:2])
