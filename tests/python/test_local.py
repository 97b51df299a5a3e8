"""The Python package in-process: reading clouds, targets, registration, parameters, the
callback, errors, threads and evaluation."""

import threading
import time

import numpy as np
import pytest

import mlsreg
from conftest import BUNNY, perturbed


# ---- reading clouds

def test_read_cloud_gives_points_and_metadata(bun000):
    assert bun000.points.shape == (40256, 3)
    assert bun000.points.dtype == np.float64
    assert bun000.normals is None
    assert bun000.path.endswith("bun000.ply")
    assert np.asarray(bun000).shape == (40256, 3)


def test_every_written_format_reads_back_the_same_points(tmp_path, bun000):
    points = bun000.points[:500]
    normals = np.tile([0.0, 0.0, 1.0], (500, 1))
    np.savetxt(tmp_path / "a.xyz", points, fmt="%.17g")
    np.save(tmp_path / "b.npy", np.hstack([points, normals]))
    xyz = mlsreg.read_cloud(tmp_path / "a.xyz")
    npy = mlsreg.read_cloud(tmp_path / "b.npy")
    np.testing.assert_array_equal(xyz.points, points)
    np.testing.assert_array_equal(npy.points, points)
    np.testing.assert_array_equal(npy.normals, normals)
    assert npy.array.shape == (500, 6)


def test_read_cloud_errors_name_the_path(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.ply"):  # as open() raises it
        mlsreg.read_cloud(tmp_path / "nope.ply")
    (tmp_path / "x.abc").write_text("1 2 3\n")
    with pytest.raises(ValueError, match="abc"):
        mlsreg.read_cloud(tmp_path / "x.abc")


def test_text_colours_are_colours_and_extra_columns_are_said(tmp_path):
    points = np.arange(30, dtype=float).reshape(10, 3)
    colours = np.tile([255, 0, 10], (10, 1))
    np.savetxt(tmp_path / "cc.txt", np.hstack([points, colours]), fmt="%g", delimiter=",",
               header="//X,Y,Z,R,G,B", comments="")
    cloud = mlsreg.read_cloud(tmp_path / "cc.txt")
    assert cloud.normals is None
    assert cloud.colors.dtype == np.uint8
    np.testing.assert_array_equal(cloud.colors, colours)
    np.savetxt(tmp_path / "i.xyz", np.hstack([points, np.ones((10, 1))]), fmt="%g")
    with pytest.warns(UserWarning, match="column 4 ignored"):
        cloud = mlsreg.read_cloud(tmp_path / "i.xyz")
    np.testing.assert_array_equal(cloud.points, points)
    with pytest.warns(UserWarning, match=r"intensity \(column 4\)"):
        cloud = mlsreg.read_cloud(tmp_path / "i.xyz", columns=["x", "y", "z", "intensity"])
    assert cloud.notes and "intensity" in cloud.notes[0]


def test_write_cloud_writes_what_the_extension_names(tmp_path, bun000):
    points = bun000.points[:200]
    normals = np.tile([0.0, 0.6, 0.8], (200, 1))
    colours = np.stack([np.arange(200) % 256, np.full(200, 7), np.full(200, 250)], 1)
    cloud = mlsreg.Cloud(points=points, normals=normals, colors=colours.astype(np.uint8))
    for name in ["a.ply", "b.pcd", "c.xyz", "d.csv", "e.npy"]:
        mlsreg.write_cloud(tmp_path / name, cloud)
        back = mlsreg.read_cloud(tmp_path / name)
        np.testing.assert_array_equal(back.points, points)
        np.testing.assert_array_equal(back.normals, normals)
        if name.endswith(".npy"):  # NPY files hold points and normals only
            assert back.colors is None
        else:
            np.testing.assert_array_equal(back.colors, colours)
    assert (tmp_path / "b.pcd").read_bytes().startswith(b"# .PCD")
    assert (tmp_path / "c.xyz").read_text().startswith("x y z nx ny nz r g b\n")
    with pytest.raises(ValueError, match="obj"):
        mlsreg.write_cloud(tmp_path / "f.obj", cloud)


def test_open3d_compressed_pcd_and_tensor_clouds(tmp_path, bun000, bun045, near_start):
    o3d = pytest.importorskip("open3d")
    legacy = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(bun000.points[:3000]))
    rgb = np.random.default_rng(1).random((3000, 3))
    legacy.colors = o3d.utility.Vector3dVector(rgb)
    # PCL's (and Open3D's) compressed PCD: LZF-compressed binary fields.
    assert o3d.io.write_point_cloud(str(tmp_path / "c.pcd"), legacy, compressed=True)
    assert b"DATA binary_compressed" in (tmp_path / "c.pcd").read_bytes()[:300]
    cloud = mlsreg.read_cloud(tmp_path / "c.pcd")
    np.testing.assert_array_equal(cloud.points, bun000.points[:3000].astype(np.float32))
    np.testing.assert_allclose(cloud.colors, rgb * 255, atol=1.0)
    # Tensor clouds are taken as legacy ones are (they failed on "dtype object").
    source = o3d.t.geometry.PointCloud(o3d.core.Tensor(bun000.points))
    target = o3d.t.geometry.PointCloud(o3d.core.Tensor(bun045.points))
    from_tensors = mlsreg.register(source, target, method="cp-sicp", init=near_start)
    from_arrays = mlsreg.register(bun000.points, bun045.points, method="cp-sicp", init=near_start)
    np.testing.assert_array_equal(from_tensors.transform, from_arrays.transform)
    coloured = o3d.t.geometry.PointCloud(o3d.core.Tensor(bun000.points[:100].astype(np.float32)))
    coloured.point["colors"] = o3d.core.Tensor(rgb[:100].astype(np.float32))
    mlsreg.write_cloud(tmp_path / "t.ply", coloured)
    np.testing.assert_allclose(mlsreg.read_cloud(tmp_path / "t.ply").colors, rgb[:100] * 255,
                               atol=1.0)


# ---- registration

def test_register_recovers_the_ground_truth(bun000, bunny_target, gt, near_start):
    result = mlsreg.register(bun000, bunny_target, init=near_start)
    error = mlsreg.evaluate(result, gt)
    # The Stanford ground truth is good to about 0.5 d; MLS-SICP lands within it.
    assert error.success and error.rmse_d < 1.0 and error.rotation_deg < 0.5
    assert result.method == "auto" and result.verified is True
    assert result.transform.shape == (4, 4)
    assert result.termination == "converged" and result.converged
    assert result.timings["total"] > 0
    assert result.sampling_distance == pytest.approx(bunny_target.sampling_distance)
    assert result.auto["early_exit"] and len(result.auto["candidates"]) == 1
    # The verified pose is polished by the finish the clouds' noise chooses, and says which.
    finish = result.auto["finish"]
    assert finish["kind"] == ("plane-to-plane" if finish["noise_d"] < finish["crossover_d"] else "mls")
    assert finish["kept"] and finish["samples"] > 2000 and finish["iterations"] >= 1
    assert finish["contradicted"] is False
    assert result.auto["rival"] is None and result.rival is None  # no rival searched
    assert result.verification["verdict"] == "verified" and result.verification["covered"] > 0
    # Verified means the agreeing samples fix every direction of motion to a standard error of at
    # most one noise sigma, a third of the band.
    v = result.verification
    assert 0 < v["worst_direction_error"] <= v["inlier_distance"] / 3
    # The bunny is smooth: its samples' normals agree with the target's to a few degrees, and
    # hardly any is left out of the directional test as lying on a sharp edge.
    assert 0 < v["normal_angle_median_deg"] < 10
    assert 0 <= v["edge_samples"] < 0.05 * v["covered"]
    # The pose covariance: symmetric, positive definite, and its extent a small share of the band.
    c = v["pose_covariance"]
    assert c.shape == (6, 6) and np.allclose(c, c.T) and np.all(np.linalg.eigvalsh(c) > 0)
    assert 0 < v["pose_translation_sigma"] < v["inlier_distance"] / 3
    assert 0 < v["pose_rotation_sigma_deg"] < 1
    # The lengths it chose from the data, in the clouds' units (metres for the bunny).
    scales = result.scales
    assert scales["mean_spacing"] == pytest.approx(bunny_target.sampling_distance)
    assert 2 * scales["median_spacing"] <= scales["working_voxel"] < 0.01
    assert scales["capture_start"] >= scales["capture_end"] > 0
    assert scales["mls_radius"] == pytest.approx(5 * scales["mean_spacing"], rel=0.2)


def test_the_trace_is_a_structured_array_of_every_iteration(bun000, bunny_target, near_start):
    result = mlsreg.register(bun000, bunny_target, method="mls-sicp", init=near_start)
    trace = result.trace
    assert trace.dtype == mlsreg.TRACE_DTYPE
    assert len(trace) == result.iterations
    np.testing.assert_array_equal(trace["iteration"], np.arange(1, result.iterations + 1))
    assert (trace["stage"] == "single").all()
    assert (trace["matched"] > 0).all() and np.all(np.diff(trace["elapsed_seconds"]) >= 0)
    assert result.auto is None and result.verified is True  # every method is verified


def test_a_registration_without_verification_says_nothing(bun000, bunny_target, near_start):
    result = mlsreg.register(bun000, bunny_target, method="cp-sicp", init=near_start, verify=False)
    assert result.verification is None and result.verified is None


def test_a_target_array_and_a_prepared_target_give_the_same_transform(bun000, bun045,
                                                                      bunny_target, near_start):
    prepared = mlsreg.register(bun000, bunny_target, method="cp-sicp", init=near_start)
    raw = mlsreg.register(bun000.points, bun045.points, method="cp-sicp", init=near_start)
    np.testing.assert_array_equal(prepared.transform, raw.transform)


def test_open3d_clouds_register_and_transform(bun000, bun045, gt, near_start):
    o3d = pytest.importorskip("open3d")
    source = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(bun000.points))
    target = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(bun045.points))
    result = mlsreg.register(source, target, method="mls-sicp", init=near_start)
    assert mlsreg.evaluate(result, gt, source=bun000.points).success
    moved = o3d.geometry.PointCloud(source).transform(result.transform)
    expected = bun000.points @ result.transform[:3, :3].T + result.transform[:3, 3]
    np.testing.assert_allclose(np.asarray(moved.points), expected, atol=1e-12)


# ---- parameters

def test_a_length_in_metres_is_the_same_as_in_units_of_d(bun000, bunny_target, near_start):
    d = bunny_target.sampling_distance
    in_d = mlsreg.register(bun000, bunny_target, method="mls-sicp", init=near_start,
                           max_iterations=3, mls_radius_d=5)
    in_m = mlsreg.register(bun000, bunny_target, method="mls-sicp", init=near_start,
                           max_iterations=3, mls_radius_d=f"{5 * d!r}m")
    assert in_m.scales["mls_radius"] == pytest.approx(5 * d, rel=1e-9)
    assert in_d.scales["user_lengths"] == []
    [given] = in_m.scales["user_lengths"]
    assert given["parameter"] == "mls.radius_d"
    assert given["value"] == pytest.approx(5 * d, rel=1e-12)
    assert given["value_d"] == pytest.approx(5.0, rel=1e-9)
    assert np.allclose(in_m.transform, in_d.transform, atol=1e-9)
    with pytest.raises(ValueError, match="mls_radius_d: .5 parsecs. is not valid"):
        mlsreg.register(bun000, bunny_target, method="mls-sicp", mls_radius_d="5 parsecs")


def test_parameters_are_the_tables_names_with_its_defaults():
    rows = {row["name"]: row for row in mlsreg.parameters()}
    assert rows["max_iterations"]["default"].isdigit()
    assert rows["mls_radius_d"]["path"] == "mls.radius_d"
    assert rows["mls_radius_d"]["default"] == "auto"
    assert "auto" in mlsreg.methods() and "mls-sicp" in mlsreg.methods()


def test_parameters_show_the_cli_flag_and_a_readable_range():
    rows = {row["name"]: row for row in mlsreg.parameters()}
    assert rows["min_normal_dot"]["flag"] == "--tau-n" and rows["min_normal_dot"]["alias"] == "tau_n"
    assert rows["num_samples"]["flag"] == "--samples"
    assert rows["max_iterations"]["range"] == "[1, 100000]"
    assert rows["seed"]["range"] == "an integer from 0 to 18446744073709551615"
    for row in rows.values():
        assert row["flag"].startswith("--") and "inf" not in row["range"], row
    # An alias never names another parameter.
    names = {row["name"]: row for row in rows.values()}
    names.update({row["path"]: row for row in rows.values()})
    for row in rows.values():
        assert names.get(row["alias"], row) is row, row["alias"]


def test_parameters_take_the_cli_flags_names_too(bun000, bunny_target, near_start):
    def run(**params):
        return mlsreg.register(bun000, bunny_target, method="mls-sicp", init=near_start,
                               max_iterations=5, **params).transform

    np.testing.assert_array_equal(run(tau_n=0.5, samples=400), run(min_normal_dot=0.5,
                                                                   num_samples=400))
    assert not np.array_equal(run(samples=400), run(samples=300))
    np.testing.assert_array_equal(run(no_warm_start=True), run(mls_warm_start=False))
    with pytest.raises(ValueError, match="tau_n and min_normal_dot name the same parameter"):
        run(min_normal_dot=0.5, tau_n=0.4)


def test_threads_must_be_in_range(bun000, bunny_target):
    for threads in (0, -1, 257):
        with pytest.raises(ValueError, match=r"threads must be in \[1, 256\]"):
            mlsreg.register(bun000, bunny_target, threads=threads)
        with pytest.raises(ValueError, match="threads"):
            mlsreg.Target(bun000.points[:100], threads=threads)


def test_the_package_shows_its_api_in_short(bun000, bunny_target, near_start):
    assert "np" not in dir(mlsreg) and "json" not in dir(mlsreg)
    assert {"register", "Target", "read_cloud", "write_cloud", "parameters"} <= set(dir(mlsreg))
    assert "built once" in mlsreg.Target.__doc__ or "prepared once" in mlsreg.Target.__doc__
    result = mlsreg.register(bun000, bunny_target, init=near_start)
    assert len(repr(result)) < 200 and repr(result).startswith("Result(method='auto'"), repr(result)
    assert "trace" not in repr(result)
    outcome = mlsreg.BatchOutcome(job={"target_id": "bun045", "source": bun000}, result=result)
    assert len(repr(outcome)) < 300 and "bun045" in repr(outcome), repr(outcome)
    failed = mlsreg.BatchOutcome(job={"target_id": "x", "source": bun000.points},
                                 error=LookupError("target 'x' not found"))
    assert repr(failed) == "BatchOutcome(target_id='x', error=LookupError(\"target 'x' not found\"))"
    reports = []
    mlsreg.register(bun000, bunny_target, init=near_start, max_iterations=1,
                    callback=reports.append)
    assert "transform" not in repr(reports[0]) and len(repr(reports[0])) < 400, repr(reports[0])


def test_parameters_change_the_registration(bun000, bunny_target, near_start):
    result = mlsreg.register(bun000, bunny_target, method="mls-sicp", init=near_start,
                             max_iterations=3, mls_radius_d=None, sicp_p=0.5)
    assert result.iterations == 3 and result.termination == "max_iterations"
    assert result.mls_radius_auto
    fixed = mlsreg.register(bun000, bunny_target, method="mls-sicp", init=near_start,
                            max_iterations=3, mls_radius_d=6)
    assert fixed.mls_radius_d == 6.0 and not fixed.mls_radius_auto


@pytest.mark.parametrize("params, message", [
    ({"max_iteration": 3}, "max_iteration: not a registration parameter"),
    ({"max_iterations": 0}, r"max_iterations must be in \[1, 100000\]"),
    ({"max_iterations": 2.5}, "max_iterations: '2.5' is not valid"),
    ({"sicp_p": "x"}, "sicp_p: 'x' is not valid"),
    ({"max_iterations": None}, "max_iterations: 'auto' is not valid"),
])
def test_bad_parameters_raise_value_error_naming_them(bun000, bunny_target, params, message):
    with pytest.raises(ValueError, match=message):
        mlsreg.register(bun000, bunny_target, **params)


def test_an_unknown_method_is_a_value_error(bun000, bunny_target):
    with pytest.raises(ValueError, match="nope"):
        mlsreg.register(bun000, bunny_target, method="nope")


# ---- bad input never crashes

@pytest.mark.parametrize("make, message", [
    (lambda p: p.astype(np.int64), "source: dtype int64 is not a floating-point type"),
    (lambda p: p.astype(np.complex128), "source: dtype complex128"),
    (lambda p: p[:, :2], r"source: shape \(40256, 2\) is not \(N, 3\) or \(N, 6\)"),
    (lambda p: p.ravel(), r"source: shape \(120768,\) is not"),
    (lambda p: np.where(np.arange(len(p))[:, None] == 7, np.nan, p), "point 7"),
    (lambda p: p[:2], "source"),
    (lambda p: None, "source: is None"),
    (lambda p: "points", "source"),
])
def test_bad_sources_raise_value_error(bun000, bunny_target, make, message):
    with pytest.raises(ValueError, match=message):
        mlsreg.register(make(bun000.points), bunny_target)


def test_bad_targets_and_starts_raise_value_error(bun000):
    with pytest.raises(ValueError, match="target: point cloud has 5 points; at least 10"):
        mlsreg.Target(bun000.points[:5])
    with pytest.raises(ValueError, match="point 3"):
        mlsreg.Target(np.where(np.arange(1000)[:, None] == 3, np.inf, bun000.points[:1000]))
    with pytest.raises(ValueError, match="target.normals: 10 normals for 1000 points"):
        mlsreg.Target(bun000.points[:1000], normals=np.ones((10, 3)))
    target = mlsreg.Target(bun000.points)
    with pytest.raises(ValueError, match=r"init: the shape must be \(4, 4\)"):
        mlsreg.register(bun000, target, init=np.eye(3))
    with pytest.raises(ValueError, match="init"):
        mlsreg.register(bun000, target, init=2 * np.eye(4))


def test_an_organised_method_needs_intrinsics(bun000, bunny_target):
    with pytest.raises(ValueError, match="rc-bl"):
        mlsreg.register(bun000, bunny_target, method="rc-bl")


# ---- the callback

def test_the_callback_sees_every_iteration_and_can_cancel(bun000, bunny_target, near_start):
    seen = []

    def callback(report):
        seen.append(report)
        return report.iteration < 2

    result = mlsreg.register(bun000, bunny_target, method="mls-sicp", init=near_start,
                             callback=callback)
    assert result.termination == "cancelled" and not result.converged
    assert [r.iteration for r in seen] == [1, 2] and result.iterations == 2
    assert isinstance(seen[0], mlsreg.IterationReport) and seen[0].transform.shape == (4, 4)
    np.testing.assert_array_equal(seen[-1].transform, result.transform)


def test_an_exception_in_the_callback_stops_and_propagates(bun000, bunny_target, near_start):
    calls = []

    def callback(report):
        calls.append(report.iteration)
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        mlsreg.register(bun000, bunny_target, method="mls-sicp", init=near_start,
                        callback=callback)
    assert calls == [1]


# ---- threads

def test_python_threads_register_in_parallel(bun000, bunny_target, near_start):
    """With the GIL released, two registrations run at the same time: the iterations of each
    (as their callbacks stamp them) interleave in time, and the results are those of one
    registration alone. A loaded machine may still run one before the other starts (the
    scheduler's choice), so the pair gets three tries to interleave; the results must match
    every time."""
    alone = mlsreg.register(bun000, bunny_target, method="mls-sicp", init=near_start)

    def run_pair():
        stamps = {0: [], 1: []}
        results = {}
        barrier = threading.Barrier(2)

        def run(k):
            barrier.wait()
            results[k] = mlsreg.register(
                bun000, bunny_target, method="mls-sicp", init=near_start,
                callback=lambda r: stamps[k].append(time.monotonic()))

        threads = [threading.Thread(target=run, args=(k,)) for k in (0, 1)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        for k in (0, 1):
            np.testing.assert_array_equal(results[k].transform, alone.transform)
            assert len(stamps[k]) == alone.iterations >= 4
        # Each thread's run spans the other's: neither ran start to end while the other waited.
        first = min(stamps, key=lambda k: stamps[k][0])
        return stamps[1 - first][0] < stamps[first][-1]

    assert any(run_pair() for _ in range(3)), "the registrations ran one after the other, 3 times"


# ---- evaluation

def test_evaluate_measures_against_ground_truth(bun000, bunny_target, gt):
    d = bunny_target.sampling_distance
    result = mlsreg.register(bun000, bunny_target, method="cp-sicp", init=gt, max_iterations=1)
    exact = mlsreg.evaluate(result, result.transform)
    assert exact.rmse_d == 0.0 and exact.success and exact.rotation_deg == 0.0
    off = perturbed(result.transform, 0.0, np.array([10 * d, 0.0, 0.0]))
    shifted = mlsreg.evaluate(result, off)
    assert shifted.rmse_d == pytest.approx(10.0, rel=1e-9)
    assert shifted.translation_d == pytest.approx(10.0, rel=1e-9) and not shifted.success
    with pytest.raises(ValueError, match="gt"):
        mlsreg.evaluate(result, np.zeros((4, 4)))


def _bumpy_sheet(n, low, high, seed, noise):
    r = np.random.default_rng(seed)
    xy = r.uniform(low, high, size=(n, 2))
    z = 0.15 * np.sin(3 * xy[:, 0]) * np.cos(2 * xy[:, 1]) + 0.1 * np.sin(5 * xy[:, 1] + 1)
    points = np.column_stack([xy, z])
    return points + r.normal(scale=noise, size=points.shape)


def _corridor(half_length, seed, pillar_spacing=2.0, noise=0.01):
    # A floor between two walls 4 m apart, 3 m tall, and pillars (0.6 m wide, 0.3 m deep, 1.5 m
    # tall) against one wall every `pillar_spacing` metres, sampled every 0.1 m.
    r = np.random.default_rng(seed)
    step = 0.1
    xs = np.arange(-half_length, half_length + 1e-9, step)
    ys = np.arange(-2.0, 2.0 + 1e-9, step)
    zs = np.arange(0.0, 3.0 + 1e-9, step)
    floor = np.array([(x, y, 0.0) for x in xs for y in ys])
    walls = np.array([(x, side, z) for x in xs for z in zs for side in (-2.0, 2.0)])
    parts = [floor, walls]
    for px in np.arange(-18.0, 18.0 + 1e-9, pillar_spacing):
        if abs(px) > half_length:
            continue
        for z in np.arange(0.0, 1.5 + 1e-9, step):
            parts.append(np.array([(px + dx, 1.7 + t, z) for t in np.arange(0.0, 0.3 + 1e-9, step / 2)
                                   for dx in (-0.3, 0.3)]))
            parts.append(np.array([(px + t, 1.7, z) for t in np.arange(-0.3, 0.3 + 1e-9, step / 2)]))
    points = np.vstack(parts)
    return points + r.normal(scale=noise, size=points.shape)


def test_auto_calls_a_pose_among_repeated_pillars_ambiguous_and_names_the_rival():
    # Pillars every 2 m along a corridor: from the truth the result verifies on its own, but a pose
    # one period along the corridor explains as much, so the result is `ambiguous`, not verified,
    # and the report names the rival candidate.
    result = mlsreg.register(_corridor(15.0, 2), mlsreg.Target(_corridor(20.0, 1)), init=np.eye(4))
    assert np.linalg.norm(result.transform[:3, 3]) < 0.05
    assert result.verified is False
    assert result.verification["verdict"] == "ambiguous"
    rival = result.auto["rival"]
    assert isinstance(rival, int)
    candidate = result.auto["candidates"][rival]
    assert candidate["origin"] == "rival"
    assert abs(np.asarray(candidate["refined"]).reshape(4, 4)[0, 3]) == pytest.approx(2.0, abs=0.2)
    assert result.auto["timings"]["rivals"] > 0
    assert result.rival["origin"] == "rival"  # on the result too, as for any method
    np.testing.assert_array_equal(result.rival["refined"], candidate["refined"])


def test_auto_finishes_a_pulled_result_and_keeps_the_finish_only_if_it_verifies():
    # A noisy bumpy sheet (sigma about 0.9 d), one iteration per stage and one global candidate
    # aligned by one iteration: the start's refinement ends `pulled` (right, a step short of the
    # data's optimum) and no candidate verifies. The finish polishes a pulled result as it does a
    # verified one; in one iteration it does not verify, so the pulled pose comes back with its
    # verdict, and the finish is reported as not kept.
    target = _bumpy_sheet(20000, -1.0, 1.0, 1, 0.01)
    source = _bumpy_sheet(12000, -0.8, 0.6, 2, 0.01)
    start = np.eye(4)
    axis = np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0])
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    angle = np.radians(4.0)
    start[:3, :3] = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
    start[:3, 3] = [0.04, -0.02, 0.002]
    result = mlsreg.register(source, target, "auto", init=start, max_iterations=1,
                             auto_candidates=1, auto_candidate_iterations=1)
    report = result.auto
    chosen = report["candidates"][report["chosen"]]
    assert report["chosen"] == 0
    assert chosen["in_start_basin"] is False
    assert chosen["score"]["verdict"] == "pulled"
    assert report["finish"]["kind"] == "mls"  # it ran on the pulled result
    assert report["finish"]["iterations"] == 1
    assert report["finish"]["kept"] is False
    assert report["finish"]["contradicted"] is False  # only a verified pose can be contradicted
    assert result.verification["verdict"] == "pulled"
    assert np.allclose(np.asarray(chosen["refined"]).reshape(4, 4), result.transform)
