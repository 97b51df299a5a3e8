#!/usr/bin/env python3
"""mlsreg against Open3D 0.16 on the same problems of the tuning split, in one run.

    bash bench/peer_comparison.sh            (installs python3-open3d, builds, scans, runs this)
    python3 bench/peer_comparison.py --scans build/tuning/scans --mlsreg build/mlsreg
    python3 bench/peer_comparison.py --scans build/tuning/scans --global build/any-start/peers_global.csv

The second form runs Open3D's global peers instead (FGR and RANSAC over FPFH matches, each
followed by point-to-plane ICP, tuned per noise level; see run_global_peers) on the tuning split
and the real bunny and dragon pairs, one row per problem for scripts/any_start_summary.py, which
sets them beside mlsreg's methods from the same problems' rotated starts (they ignore the start).

Problems: the tuning split (scripts/tuning-split.sh: 4 CGAL meshes x 12 virtual-scanner views,
sigma = 0, 0.8 d and 2 d, each view registered to its neighbour from the scanner's 30-degree
start, full resolution). Every method runs on one thread (OMP_NUM_THREADS=1, mlsreg --threads 1,
one problem at a time).

mlsreg runs with default parameters (MLS-SICP, the product; CP-SICP and G-ICP for reference).
Open3D's point-to-plane ICP and G-ICP are tuned on this split, per noise level: for each method
and sigma the max correspondence distance is chosen from a grid (in units of the target's d) as
the value with the most successes, ties broken by the lower median RMSE. The normal radius of
point-to-plane is 5 d (30 neighbours at most), the radius mlsreg analyses at; 30 ICP iterations
is Open3D's default, raised to 100 as for mlsreg.

Success and RMSE as in `mlsreg eval`: RMSE of the source points under the estimate against the
ground truth, in units of the target's mean nearest-neighbour distance d; success below 5 d.
Time per problem: Open3D's preparation (normals) plus registration, reading the files not
counted; mlsreg's whole `register` process, timed from its start to its exit (starting, reading
both files, the target's build, registration, verdict, writing the result), as a user runs it.
"""
import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
import numpy as np  # noqa: E402

SIGMAS = ["0", "0.8", "2"]
MESHES = ["elephant", "armadillo", "dino", "homer"]
CORRESPONDENCE_GRID_D = [2.0, 5.0, 10.0, 20.0]
NORMAL_RADIUS_D = 5.0
MAX_ITERATIONS = 100


def matrix(text):
    return np.array([float(v) for v in text.split()]).reshape(4, 4)


def problems(scans, sigma):
    out = []
    for mesh in MESHES:
        folder = os.path.join(scans, mesh, f"sigma{sigma}")
        with open(os.path.join(folder, "pairs.csv")) as f:
            for row in csv.DictReader(f):
                out.append({"id": row["id"], "source": os.path.join(folder, row["source"]),
                            "target": os.path.join(folder, row["target"]),
                            "gt": matrix(row["gt"]), "init": matrix(row["init"]) if row.get("init") else np.eye(4)})
    return out


def rmse_d(points, estimate, truth, d):
    a = points @ estimate[:3, :3].T + estimate[:3, 3]
    b = points @ truth[:3, :3].T + truth[:3, 3]
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1)))) / d


def run_open3d(o3d, problem, method, max_corr_d, cache):
    key = (problem["source"], problem["target"])
    if key not in cache:
        source = o3d.io.read_point_cloud(problem["source"])
        target = o3d.io.read_point_cloud(problem["target"])
        d = float(np.mean(np.asarray(target.compute_nearest_neighbor_distance())))
        cache.clear()
        cache[key] = (source, target, d)
    source, target, d = cache[key]
    reg = o3d.pipelines.registration
    criteria = reg.ICPConvergenceCriteria(max_iteration=MAX_ITERATIONS)
    start = time.perf_counter()
    if method == "o3d-point-to-plane":
        src, tgt = o3d.geometry.PointCloud(source), o3d.geometry.PointCloud(target)
        param = o3d.geometry.KDTreeSearchParamHybrid(radius=NORMAL_RADIUS_D * d, max_nn=30)
        tgt.estimate_normals(param)
        result = reg.registration_icp(src, tgt, max_corr_d * d, problem["init"],
                                      reg.TransformationEstimationPointToPlane(), criteria)
    else:
        result = reg.registration_generalized_icp(
            source, target, max_corr_d * d, problem["init"],
            reg.TransformationEstimationForGeneralizedICP(), criteria)
    seconds = time.perf_counter() - start
    points = np.asarray(source.points)
    error = rmse_d(points, np.asarray(result.transformation), problem["gt"], d)
    return error, seconds


# ---- global peers (--global): Open3D's FGR and RANSAC over FPFH matches, each followed by its
# point-to-plane ICP, as in Open3D's global registration tutorial (voxel v, normals at 2 v with 30
# neighbours, FPFH at 5 v with 100, RANSAC distance 1.5 v with the EdgeLength(0.9) and
# Distance(1.5 v) checkers and (100000, 0.999) criteria, FGR at 0.5 v with decrease_mu set
# explicitly, since the 0.16 binding's default differs from the C++ one). Tuned per noise level
# (and on the real set) over a grid of v and of the ICP's correspondence distance, by successes,
# ties by median RMSE. They ignore the start pose.
GLOBAL_VOXEL_GRID_D = [2.0, 3.0, 5.0]
GLOBAL_ICP_GRID_D = [2.0, 5.0]


def real_problems(shared):
    out = []
    for folder in ["stanford_bunny", "stanford_dragon_stand"]:
        root = os.path.join(shared, "data", "real", folder)
        with open(os.path.join(root, "pairs.csv")) as f:
            for row in csv.DictReader(f):
                out.append({"id": row["id"], "source": os.path.join(root, row["source"]),
                            "target": os.path.join(root, row["target"]), "gt": matrix(row["gt"]),
                            "init": matrix(row["gt"])})
    return out


def run_open3d_global(o3d, problem, method, voxel_d, icp_grid_d, cache):
    """RMSE/d and seconds after the global method and after its ICP, per ICP distance."""
    key = (problem["source"], problem["target"])
    if cache.get("key") != key:
        source = o3d.io.read_point_cloud(problem["source"])
        target = o3d.io.read_point_cloud(problem["target"])
        d = float(np.mean(np.asarray(target.compute_nearest_neighbor_distance())))
        tgt_normals = o3d.geometry.PointCloud(target)
        tgt_normals.estimate_normals(
            o3d.geometry.KDTreeSearchParamHybrid(radius=NORMAL_RADIUS_D * d, max_nn=30))
        cache.clear()
        cache.update(key=key, source=source, target=target, d=d, target_normals=tgt_normals)
    source, target, d = cache["source"], cache["target"], cache["d"]
    reg = o3d.pipelines.registration
    v = voxel_d * d
    start = time.perf_counter()
    prepared = []
    for cloud in (source, target):
        down = cloud.voxel_down_sample(v)
        down.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=2 * v, max_nn=30))
        fpfh = reg.compute_fpfh_feature(down, o3d.geometry.KDTreeSearchParamHybrid(radius=5 * v,
                                                                                    max_nn=100))
        prepared.append((down, fpfh))
    (sd, sf), (td, tf) = prepared
    if method == "o3d-ransac":
        result = reg.registration_ransac_based_on_feature_matching(
            sd, td, sf, tf, True, 1.5 * v, reg.TransformationEstimationPointToPoint(False), 3,
            [reg.CorrespondenceCheckerBasedOnEdgeLength(0.9),
             reg.CorrespondenceCheckerBasedOnDistance(1.5 * v)],
            reg.RANSACConvergenceCriteria(100000, 0.999))
    else:
        option = reg.FastGlobalRegistrationOption(
            division_factor=1.4, use_absolute_scale=False, decrease_mu=True,
            maximum_correspondence_distance=0.5 * v, iteration_number=64, tuple_scale=0.95,
            maximum_tuple_count=1000)
        result = reg.registration_fgr_based_on_feature_matching(sd, td, sf, tf, option)
    global_seconds = time.perf_counter() - start
    points = np.asarray(source.points)
    out = {"global": (rmse_d(points, np.asarray(result.transformation), problem["gt"], d),
                      global_seconds)}
    criteria = reg.ICPConvergenceCriteria(max_iteration=MAX_ITERATIONS)
    for icp_d in icp_grid_d:
        t = time.perf_counter()
        refined = reg.registration_icp(source, cache["target_normals"], icp_d * d,
                                       result.transformation,
                                       reg.TransformationEstimationPointToPlane(), criteria)
        out[icp_d] = (rmse_d(points, np.asarray(refined.transformation), problem["gt"], d),
                      global_seconds + time.perf_counter() - t)
    return out


def run_global_peers(o3d, sets, out_path):
    """Per problem rows of the tuned global peers, to out_path (scripts/any_start_summary.py)."""
    rows_out = []
    for set_name, sigma, todo in sets:
        for method in ["o3d-fgr", "o3d-ransac"]:
            best = None
            for voxel_d in GLOBAL_VOXEL_GRID_D:
                cache = {}
                per_problem = [run_open3d_global(o3d, p, method, voxel_d, GLOBAL_ICP_GRID_D, cache)
                               for p in todo]
                for icp_d in GLOBAL_ICP_GRID_D:
                    rows = [{"rmse_d": r[icp_d][0], "seconds": r[icp_d][1],
                             "global_rmse_d": r["global"][0], "global_seconds": r["global"][1]}
                            for r in per_problem]
                    successes, median_rmse, _ = summarise(rows)
                    score = (successes, -median_rmse)
                    if best is None or score > best[0]:
                        best = (score, voxel_d, icp_d, rows)
            _, voxel_d, icp_d, rows = best
            successes, median_rmse, seconds = summarise(rows)
            alone = sum(r["global_rmse_d"] < 5.0 for r in rows)
            print(f"{set_name:9s} sigma {sigma or '-':>3s} {method + '+icp':16s} {successes:>3d}/"
                  f"{len(rows):<3d} (global alone {alone:>3d}) median RMSE {median_rmse:.4f} d, "
                  f"median {seconds:.3f} s (global {statistics.median(r['global_seconds'] for r in rows):.3f} s);"
                  f" tuned v = {voxel_d:g} d, ICP {icp_d:g} d", flush=True)
            for p, r in zip(todo, rows):
                rows_out.append({"set": set_name, "sigma": sigma, "id": p["id"],
                                 "method": method + "+icp", "rmse_d": r["rmse_d"],
                                 "seconds": r["seconds"], "global_rmse_d": r["global_rmse_d"],
                                 "global_seconds": r["global_seconds"], "voxel_d": voxel_d,
                                 "icp_d": icp_d})
    with open(out_path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows_out[0].keys()))
        writer.writeheader()
        writer.writerows(rows_out)


def percentile90(values):
    """The 90th percentile, linearly interpolated (numpy's default; `mlsreg eval` prints the same)."""
    values = sorted(values)
    if not values:
        return float("nan")
    at = 0.9 * (len(values) - 1)
    below = int(at)
    above = values[min(below + 1, len(values) - 1)]
    return values[below] + (at - below) * (above - values[below])


def summarise(rows):
    ok = [r for r in rows if r["rmse_d"] < 5.0]
    median_rmse = statistics.median(r["rmse_d"] for r in ok) if ok else float("nan")
    return len(ok), median_rmse, statistics.median(r["seconds"] for r in rows)


def p90_of_successes(rows):
    return percentile90([r["rmse_d"] for r in rows if r["rmse_d"] < 5.0])


def run_mlsreg(o3d, mlsreg, todo, methods):
    """Each problem as a whole `mlsreg register` process per method (defaults, one thread), timed
    from its start to its exit; RMSE as run_open3d's, from the transform it writes."""
    rows = {method: [] for method in methods}
    for p in todo:
        points = np.asarray(o3d.io.read_point_cloud(p["source"]).points)
        target = o3d.io.read_point_cloud(p["target"])
        d = float(np.mean(np.asarray(target.compute_nearest_neighbor_distance())))
        init = " ".join("%.17g" % v for v in p["init"].ravel())
        for method in methods:
            with tempfile.TemporaryDirectory() as tmp:
                result = os.path.join(tmp, "result.json")
                start = time.perf_counter()
                subprocess.run([mlsreg, "register", "--source", p["source"], "--target",
                                p["target"], "--init", init, "--method", method, "--threads", "1",
                                "--quiet", "--json", result],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                seconds = time.perf_counter() - start
                error = float("inf")  # no result: a failure
                if os.path.exists(result):
                    with open(result) as f:
                        estimate = np.array(json.load(f)["transform"], dtype=float).reshape(4, 4)
                    error = rmse_d(points, estimate, p["gt"], d)
            rows[method].append({"rmse_d": error, "seconds": seconds})
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scans", default="build/tuning/scans")
    parser.add_argument("--mlsreg", default="build/mlsreg")
    parser.add_argument("--methods", default="mls-sicp,cp-sicp,g-icp")
    parser.add_argument("--out", help="CSV of the summary rows")
    parser.add_argument("--global", dest="global_out", metavar="CSV",
                        help="instead: Open3D's global peers (FGR, RANSAC, each + ICP) on the "
                             "tuning split and the real bunny and dragon pairs, per problem to CSV")
    parser.add_argument("--shared", default="../shared")
    args = parser.parse_args()
    import open3d as o3d
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    if args.global_out:
        o3d.utility.random.seed(1)
        sets = [("synthetic", sigma, problems(args.scans, sigma)) for sigma in SIGMAS]
        sets.append(("real", "", real_problems(args.shared)))
        run_global_peers(o3d, sets, args.global_out)
        return 0

    summary = []
    print(f"Open3D {o3d.__version__}; one thread per method; success: RMSE < 5 d")
    for sigma in SIGMAS:
        todo = problems(args.scans, sigma)
        results = run_mlsreg(o3d, args.mlsreg, todo, args.methods.split(","))
        tuned = {}
        for method in ["o3d-point-to-plane", "o3d-gicp"]:
            best = None
            cache = {}
            for max_corr_d in CORRESPONDENCE_GRID_D:
                rows = []
                for p in todo:
                    error, seconds = run_open3d(o3d, p, method, max_corr_d, cache)
                    rows.append({"rmse_d": error, "seconds": seconds})
                successes, median_rmse, _ = summarise(rows)
                score = (successes, -median_rmse)
                if best is None or score > best[0]:
                    best = (score, max_corr_d, rows)
            results[method] = best[2]
            tuned[method] = best[1]
        print(f"\n== sigma = {sigma} d ({len(todo)} problems); Open3D max correspondence distance "
              f"tuned here: point-to-plane {tuned['o3d-point-to-plane']:g} d, "
              f"G-ICP {tuned['o3d-gicp']:g} d")
        print(f"{'method':22s} {'successes':>10s} {'median RMSE/d':>14s} {'90th pct':>10s} "
              f"{'median time':>12s} {'time / O3D p2plane':>19s}")
        reference = summarise(results["o3d-point-to-plane"])[2]
        for method, rows in results.items():
            successes, median_rmse, seconds = summarise(rows)
            label = method if method.startswith("o3d") else f"mlsreg {method}"
            p90 = p90_of_successes(rows)
            print(f"{label:22s} {successes:>5d}/{len(rows):<4d} {median_rmse:>14.4f} {p90:>10.4f} "
                  f"{seconds:>10.3f} s {seconds / reference:>19.2f}")
            summary.append({"sigma_d": sigma, "method": label, "successes": successes,
                            "problems": len(rows), "median_rmse_d": median_rmse, "p90_rmse_d": p90,
                            "median_seconds": seconds, "time_ratio_to_o3d_p2plane":
                            seconds / reference, "o3d_max_corr_d": tuned.get(method, "")})
    if args.out:
        with open(args.out, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(summary[0].keys()))
            writer.writeheader()
            writer.writerows(summary)
    return 0


if __name__ == "__main__":
    sys.exit(main())
