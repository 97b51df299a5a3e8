#!/usr/bin/env python3
"""Multi-view alignment against ground truth: mlsreg's rows and Open3D 0.16's multiway
registration on the same scans, from the same perturbed poses, with the same pairs.

Start: view 0 at its true pose (the anchor), every other view's true pose turned by 10 degrees
about a seeded random axis through its centroid and moved by 10 d (the pairwise protocol).

Rows (scripts/multiview-eval.sh runs this):
  chained MLS-SICP     `mlsreg align --pairs sequential`: each view registered to the previous
                       one and the poses composed (a tree: the graph changes nothing)
  AlignScans MLS-SICP  `mlsreg align` with MLS-SICP edges (defaults) and the pose graph
  AlignScans CP-SICP   the same with CP-SICP edges
  Open3D multiway      Open3D's pipeline (its multiway-registration tutorial): point-to-plane ICP
                       per pair, information from get_information_matrix_from_point_clouds, the
                       chained odometry as start, global_optimization (Levenberg-Marquardt,
                       edge_prune_threshold 0.25, preference_loop_closure 2); its max
                       correspondence distance is tuned per noise level on the tuning split
                       (--tuning-scans: the same protocol on the unreported meshes, grid
                       O3D_GRID_D, lowest median pose error); on the real sets the value tuned
                       at sigma = 0 (labelled)

The pairs: a loop (view i to i+1 and the last to the first) for the virtual turntables and the
dragon; for the bunny's 10 scans (no ring) the pairs whose overlap under the start poses is at
least 0.3, as mlsreg align --pairs overlap found them, given to Open3D too.

Per view: the absolute pose error in the frame of view 0, as the RMS displacement of the view's
points between the estimated and the true pose (units of d), and its rotation. Per set: the
merged cloud's RMSE against the mesh surface (synthetic sets; Open3D's RaycastingScene), and for
mlsreg the loop-closure error of the chained edges.
"""
import argparse
import csv
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
import numpy as np  # noqa: E402

SIGMAS = ["0", "0.8", "2"]
# Without --tuning-scans: the distances tuned for Open3D's pairwise point-to-plane on the tuning
# split (docs/evaluation.md); --tuning-scans replaces them by values tuned for its multiway use.
O3D_MAX_CORR_D = {"0": 2.0, "0.8": 20.0, "2": 20.0, "real": 5.0}
O3D_GRID_D = [2.0, 5.0, 10.0, 20.0]
NORMAL_RADIUS_D = 5.0
PERTURB_DEG, PERTURB_D, SEED = 10.0, 10.0, 1
ROWS = ["chained MLS-SICP", "AlignScans MLS-SICP", "AlignScans CP-SICP", "Open3D multiway"]


def matrix(text):
    return np.array([float(v) for v in text.replace(",", " ").split()]).reshape(4, 4)


def rotation_deg(r):
    return math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(r) - 1) / 2))))


def read_points(path):
    import open3d as o3d
    return np.asarray(o3d.io.read_point_cloud(path).points)


def mean_spacing(points):
    import open3d as o3d
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    return float(np.mean(pcd.compute_nearest_neighbor_distance()))


def perturbation(rng, d, center):
    """A turn of PERTURB_DEG about a random axis through `center`, then PERTURB_D d in a random
    direction (the pairwise protocol of `mlsreg eval`, about the view's centroid)."""
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    a = math.radians(PERTURB_DEG)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    m = np.eye(4)
    m[:3, :3] = np.eye(3) + math.sin(a) * k + (1 - math.cos(a)) * k @ k
    direction = rng.normal(size=3)
    m[:3, 3] = center - m[:3, :3] @ center + PERTURB_D * d * direction / np.linalg.norm(direction)
    return m


def perturbed_starts(clouds, truth, d):
    rng = np.random.default_rng(SEED)
    to0 = np.linalg.inv(truth[0])
    start = [to0 @ truth[0]]
    for points, t in zip(clouds[1:], truth[1:]):
        pose = to0 @ t
        center = pose[:3, :3] @ points.mean(axis=0) + pose[:3, 3]
        start.append(perturbation(rng, d, center) @ pose)
    return start


def loop_pairs(n):
    return [(i, i + 1) for i in range(n - 1)] + [(n - 1, 0)]


def tune_open3d(o3d, tuning_scans):
    """Per noise level, the grid distance with the lowest median (over the tuning meshes) of the
    median pose error of Open3D multiway on loops of the tuning split's views."""
    meshes = sorted(m for m in os.listdir(tuning_scans)
                    if os.path.isdir(os.path.join(tuning_scans, m)))
    tuned = {}
    for sigma in SIGMAS:
        scores = {}
        for distance in O3D_GRID_D:
            medians = []
            for mesh in meshes:
                folder = os.path.join(tuning_scans, mesh, f"sigma{sigma}")
                with open(os.path.join(folder, "poses.csv")) as f:
                    rows = list(csv.DictReader(f))
                clouds = [read_points(os.path.join(folder, "view_%03.0f.ply" % float(r["angle_deg"])))
                          for r in rows]
                truth = [matrix(r["camera_to_world"]) for r in rows]
                d = statistics.mean(mean_spacing(c) for c in clouds)
                start = perturbed_starts(clouds, truth, d)
                poses, _ = run_open3d(o3d, clouds, start, loop_pairs(len(clouds)), (distance * d, d))
                medians.append(statistics.median(pose_errors(clouds, poses, truth, d)[0][1:]))
            scores[distance] = statistics.median(medians)
            print(f"tuning Open3D multiway: sigma {sigma} d, {distance:g} d -> median pose error "
                  f"{scores[distance]:.3f} d", flush=True)
        tuned[sigma] = min(scores, key=scores.get)
    tuned["real"] = tuned["0"]
    return tuned


def write_rows(path, poses):
    with open(path, "w") as f:
        for p in poses:
            f.write(" ".join("%.12g" % v for v in p.ravel()) + "\n")


def conf_poses(path, names):
    poses = {}
    for line in open(path):
        f = line.split()
        if f and f[0] == "bmesh":
            x, y, z, w = map(float, f[5:9])
            r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                          [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                          [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
            p = np.eye(4)
            p[:3, :3] = r.T  # the scanalyze convention (lib/include/mlsreg/io/pose_files.h)
            p[:3, 3] = list(map(float, f[2:5]))
            poses[f[1]] = p
    return [poses[n] for n in names]


def sets(args):
    """(label, sigma, scan paths, true poses, mesh path or None, pairs policy)."""
    meshes = dict(m.split("=", 1) for m in args.mesh)
    for name, mesh in meshes.items():
        for sigma in SIGMAS:
            folder = os.path.join(args.scans, name, f"sigma{sigma}")
            with open(os.path.join(folder, "poses.csv")) as f:
                rows = list(csv.DictReader(f))
            paths = [os.path.join(folder, "view_%03.0f.ply" % float(r["angle_deg"])) for r in rows]
            yield name, sigma, paths, [matrix(r["camera_to_world"]) for r in rows], mesh, "loop"
    bunny = os.path.join(args.shared, "data/real/stanford_bunny")
    names = ["bun000.ply", "bun045.ply", "bun090.ply", "bun180.ply", "bun270.ply", "bun315.ply",
             "chin.ply", "ear_back.ply", "top2.ply", "top3.ply"]
    yield ("real bunny", "real", [os.path.join(bunny, n) for n in names],
           conf_poses(os.path.join(bunny, "bun.conf"), names), None, "overlap")
    dragon = os.path.join(args.shared, "data/real/stanford_dragon_stand")
    names = ["dragonStandRight_%d.ply" % a for a in range(0, 360, 24)]
    yield ("real dragon", "real", [os.path.join(dragon, n) for n in names],
           conf_poses(os.path.join(dragon, "dragonStandRight.conf"), names), None, "loop")


def run_mlsreg(mlsreg, paths, start, pairs, method, work, extra=()):
    write_rows(os.path.join(work, "start.txt"), start)
    out = os.path.join(work, f"align-{method}-{pairs}.json")
    t = time.perf_counter()
    run = subprocess.run([mlsreg, "align", "--scans", *paths, "--poses",
                          os.path.join(work, "start.txt"), "--pairs", pairs, "--method", method,
                          "--threads", "2", "--json", out, *extra], stdout=subprocess.DEVNULL)
    seconds = time.perf_counter() - t
    # Exit 4: some scan rests on no verified edge (its pose is still written and scored here;
    # j["unverified_scans"] names it).
    if run.returncode not in (0, 4):
        raise subprocess.CalledProcessError(run.returncode, run.args)
    j = json.load(open(out))
    poses = [np.array(s["pose"]).reshape(4, 4) for s in j["scans"]]
    return poses, j, seconds


def run_open3d(o3d, clouds, start, pairs, max_corr):
    reg = o3d.pipelines.registration
    t = time.perf_counter()
    pcds = []
    for points in clouds:
        pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
        pcd.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=NORMAL_RADIUS_D * max_corr[1],
                                                                  max_nn=30))
        pcds.append(pcd)
    n = len(pcds)
    graph = reg.PoseGraph()
    edges = {}
    for (i, j) in pairs:  # (target i, source j): register j onto i, as mlsreg's edges
        init = np.linalg.inv(start[i]) @ start[j]
        icp = reg.registration_icp(pcds[j], pcds[i], max_corr[0], init,
                                   reg.TransformationEstimationPointToPlane(),
                                   reg.ICPConvergenceCriteria(max_iteration=100))
        info = reg.get_information_matrix_from_point_clouds(pcds[j], pcds[i], max_corr[0],
                                                            icp.transformation)
        edges[(i, j)] = (icp.transformation, info)
    # Start: odometry chained along a spanning tree from view 0 (the tutorial's odometry).
    poses = {0: np.eye(4)}
    frontier = [0]
    while frontier:
        at = frontier.pop(0)
        for (i, j), (t_ij, _) in edges.items():
            if i == at and j not in poses:
                poses[j] = poses[i] @ t_ij
                frontier.append(j)
            elif j == at and i not in poses:
                poses[i] = poses[j] @ np.linalg.inv(t_ij)
                frontier.append(i)
    for k in range(n):
        graph.nodes.append(reg.PoseGraphNode(poses.get(k, np.eye(4))))
    for (i, j), (t_ij, info) in edges.items():
        # Open3D's edge (source, target, T) asks pose[target]^-1 pose[source] = T^-1 ... in its
        # convention T maps the source node's frame into the target's: source j, target i.
        uncertain = abs(i - j) != 1
        graph.edges.append(reg.PoseGraphEdge(j, i, t_ij, info, uncertain=uncertain))
    option = reg.GlobalOptimizationOption(max_correspondence_distance=max_corr[0],
                                          edge_prune_threshold=0.25,
                                          preference_loop_closure=2.0, reference_node=0)
    reg.global_optimization(graph, reg.GlobalOptimizationLevenbergMarquardt(),
                            reg.GlobalOptimizationConvergenceCriteria(), option)
    seconds = time.perf_counter() - t
    return [np.asarray(node.pose) for node in graph.nodes], seconds


def pose_errors(clouds, estimate, truth, d):
    """Per view: RMS displacement (units of d) and rotation (deg), in view 0's frame."""
    to0 = np.linalg.inv(truth[0])
    rms, rot = [], []
    for points, e, t in zip(clouds, estimate, truth):
        expected = to0 @ t
        diff = points @ (e[:3, :3] - expected[:3, :3]).T + (e[:3, 3] - expected[:3, 3])
        rms.append(float(np.sqrt((diff ** 2).sum(axis=1).mean())) / d)
        rot.append(rotation_deg(e[:3, :3].T @ expected[:3, :3]))
    return rms, rot


def voxel_merged(o3d, clouds, estimate, d):
    """Open3D 0.16's counterpart of --resample: the merged cloud voxel-downsampled at d
    (voxel centroids), in view 0's frame."""
    points = np.vstack([c @ e[:3, :3].T + e[:3, 3] for c, e in zip(clouds, estimate)])
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points)).voxel_down_sample(d)
    return np.asarray(cloud.points)


def merged_rmse(o3d, clouds, estimate, truth, mesh_path, d):
    mesh = o3d.io.read_triangle_mesh(mesh_path)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
    merged = np.vstack([points @ (truth[0] @ e)[:3, :3].T + (truth[0] @ e)[:3, 3]
                        for points, e in zip(clouds, estimate)])
    distance = scene.compute_distance(o3d.core.Tensor(merged.astype(np.float32))).numpy()
    return float(np.sqrt((distance.astype(np.float64) ** 2).mean())) / d


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mlsreg", default="build/mlsreg")
    parser.add_argument("--scans", default="build/evaluation/scans")
    parser.add_argument("--shared", default="../shared")
    parser.add_argument("--out", default="build/multiview")
    parser.add_argument("--mesh", action="append", default=[], help="name=path, as mlsreg-scan")
    parser.add_argument("--only", help="comma-separated set labels (e.g. 'real dragon')")
    parser.add_argument("--tuning-scans", help="the tuning split's scans: tune Open3D there")
    args = parser.parse_args()
    import open3d as o3d
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    os.makedirs(args.out, exist_ok=True)
    if args.tuning_scans:
        O3D_MAX_CORR_D.update(tune_open3d(o3d, args.tuning_scans))
        with open(os.path.join(args.out, "open3d_tuned.json"), "w") as f:
            json.dump(O3D_MAX_CORR_D, f)
    print("Open3D multiway max correspondence distance (units of d):", O3D_MAX_CORR_D, flush=True)
    results = []
    only = set(args.only.split(",")) if args.only else None
    for label, sigma, paths, truth, mesh, policy in sets(args):
        if only and label not in only:
            continue
        clouds = [read_points(p) for p in paths]
        d = statistics.mean(mean_spacing(c) for c in clouds)
        start = perturbed_starts(clouds, truth, d)
        with tempfile.TemporaryDirectory() as work:
            estimates = {}
            chained, _, s0 = run_mlsreg(args.mlsreg, paths, start, "sequential", "mls-sicp", work)
            estimates["chained MLS-SICP"] = (chained, s0, None)
            # Its merged cloud also resampled onto the joint MLS surface (mlsreg align --resample;
            # the seconds then include the resampling).
            resampled_path = os.path.join(work, "resampled.ply")
            mls, j, s1 = run_mlsreg(args.mlsreg, paths, start, policy, "mls-sicp", work,
                                    ["--merged", resampled_path, "--resample"] if mesh else [])
            estimates["AlignScans MLS-SICP"] = (mls, s1, j)
            resampled = [read_points(resampled_path)] if mesh else None
            cp, jcp, s2 = run_mlsreg(args.mlsreg, paths, start, policy, "cp-sicp", work)
            estimates["AlignScans CP-SICP"] = (cp, s2, jcp)
            pairs = [(e["from"], e["to"]) for e in j["edges"]]
            corr = O3D_MAX_CORR_D[sigma] * d
            o3d_poses, s3 = run_open3d(o3d, clouds, start, pairs, (corr, d))
            estimates["Open3D multiway"] = (o3d_poses, s3, None)
        for row in ROWS:
            poses, seconds, report = estimates[row]
            rms, rot = pose_errors(clouds, poses, truth, d)
            entry = {"set": label, "sigma_d": sigma, "row": row, "views": len(paths),
                     "o3d_max_corr_d": O3D_MAX_CORR_D[sigma] if row == "Open3D multiway" else "",
                     "pairs": policy if row != "chained MLS-SICP" else "sequential",
                     "median_pose_rmse_d": statistics.median(rms[1:]),
                     "max_pose_rmse_d": max(rms[1:]),
                     "median_rotation_deg": statistics.median(rot[1:]),
                     "views_within_5d": sum(r < 5 for r in rms[1:]), "seconds": seconds,
                     "loop_closure_error_d": report["loop_closure_error_d"] if report else "",
                     "max_drift_removed_d": max(v["drift_removed_d"] for v in report["scans"])
                     if report else "",
                     "edges_dropped": sum(not e["kept"] for e in report["edges"]) if report else "",
                     "merged_rmse_d": merged_rmse(o3d, clouds, poses, truth, mesh, d) if mesh else "",
                     "resampled_rmse_d": merged_rmse(o3d, resampled, [np.eye(4)], truth, mesh, d)
                     if mesh and row == "AlignScans MLS-SICP" else "",
                     "o3d_voxel_rmse_d": merged_rmse(o3d, [voxel_merged(o3d, clouds, poses, d)],
                                                     [np.eye(4)], truth, mesh, d)
                     if mesh and row == "AlignScans MLS-SICP" else ""}
            results.append(entry)
            print(f"{label:12s} sigma {sigma:>4s}  {row:20s}  pose RMSE median "
                  f"{entry['median_pose_rmse_d']:8.3f} d  max {entry['max_pose_rmse_d']:8.3f} d  "
                  f"rot {entry['median_rotation_deg']:6.3f} deg  merged "
                  f"{entry['merged_rmse_d'] if mesh else float('nan'):7.3f} d  {seconds:6.1f} s",
                  flush=True)
    with open(os.path.join(args.out, "multiview.csv"), "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(results[0].keys()))
        writer.writeheader()
        writer.writerows(results)
    print("wrote", os.path.join(args.out, "multiview.csv"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
