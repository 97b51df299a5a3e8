#include "mlsreg/multiview/align_scans.h"

#include <Eigen/Geometry>
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <queue>
#include <thread>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "mlsreg/geometry/sampling.h"
#include "mlsreg/geometry/target.h"
#include "mlsreg/registration/registration.h"
#include "mlsreg/registration/verification.h"

namespace mlsreg {
namespace {

using TargetPtr = std::shared_ptr<const Target>;

// Correspondences closer than this (units of d) with agreeing normals enter the information.
constexpr double kInformationGateD = 3.0;
constexpr double kInformationNormalDot = 0.7;

Vec3 Apply(const Matrix4& m, const Vec3& p) {
  return m.topLeftCorner<3, 3>() * p + m.topRightCorner<3, 1>();
}

// The samples of a scan that score overlaps and information: its target's voxel samples with
// normals (built with the target), else every 8th point with the target's normals.
struct Samples {
  std::vector<Vec3> points, normals;
  bool oriented = false;
};

Samples SamplesOf(const Target& target) {
  Samples s;
  if (const FeatureCloud* f = target.features(); f != nullptr && f->size() > 0) {
    s.points = f->points;
    s.normals = f->normals;
    s.oriented = f->oriented;
    return s;
  }
  for (std::size_t i = 0; i < target.points().size(); i += 8) {
    s.points.push_back(target.points()[i]);
    s.normals.push_back(target.surface().normals[i]);
  }
  s.oriented = target.surface().oriented;
  return s;
}

// The point-to-plane system of an edge at its result: samples of `to` under `relative`, each
// against the nearest point of `from` and its normal, a = [q x n; n], H = sum a a^T / (N d^2).
struct Information {
  Matrix6 matrix = Matrix6::Zero();
  int correspondences = 0;
};

Information EdgeInformation(const Target& from, const Samples& to, const Matrix4& relative,
                            double d) {
  Information info;
  const Eigen::Matrix3d rotation = relative.topLeftCorner<3, 3>();
  for (std::size_t k = 0; k < to.points.size(); ++k) {
    const Vec3 q = Apply(relative, to.points[k]);
    const Neighbor nearest = from.tree().Nearest(q);
    if (std::sqrt(nearest.distance_squared) > kInformationGateD * d) continue;
    const Vec3& n = from.surface().normals[nearest.index];
    if (std::abs(n.dot(rotation * to.normals[k])) < kInformationNormalDot) continue;
    Eigen::Matrix<double, 6, 1> a;
    a << q.cross(n), n;
    info.matrix += a * a.transpose();
    ++info.correspondences;
  }
  if (info.correspondences > 0) info.matrix /= info.correspondences * d * d;
  return info;
}

// The share of `points` (under `relative`) with a point of `target` within `distance`.
double NearShare(const Target& target, const std::vector<Vec3>& points, const Matrix4& relative,
                 double distance) {
  if (points.empty()) return 0.0;
  int near = 0;
  for (const Vec3& p : points) {
    near += target.tree().Nearest(Apply(relative, p)).distance_squared <= distance * distance;
  }
  return static_cast<double>(near) / static_cast<double>(points.size());
}

std::vector<std::pair<int, int>> CandidatePairs(PairPolicy policy, int n) {
  std::vector<std::pair<int, int>> pairs;
  if (policy == PairPolicy::kOverlap) {
    for (int i = 0; i < n; ++i) {
      for (int j = i + 1; j < n; ++j) pairs.emplace_back(i, j);
    }
    return pairs;
  }
  for (int i = 0; i + 1 < n; ++i) pairs.emplace_back(i, i + 1);
  if (policy == PairPolicy::kLoop && n > 2) pairs.emplace_back(n - 1, 0);
  return pairs;
}

double RotationDegrees(const Matrix4& m) {
  const Eigen::AngleAxisd aa(Eigen::Matrix3d(m.topLeftCorner<3, 3>()));
  return std::abs(aa.angle()) * 180.0 / M_PI;
}

// Poses composed along a breadth-first spanning tree from the anchor, through trusted edges
// wherever they reach.
std::vector<Matrix4> ChainedPoses(int n, int anchor, const std::vector<PoseGraphEdge>& edges) {
  std::vector<Matrix4> poses(n, Matrix4::Identity());
  std::vector<bool> seen(n, false);
  seen[anchor] = true;
  for (const bool trusted_only : {true, false}) {
    std::queue<int> frontier;
    for (int i = 0; i < n; ++i) {
      if (seen[i]) frontier.push(i);
    }
    while (!frontier.empty()) {
      const int at = frontier.front();
      frontier.pop();
      for (const PoseGraphEdge& e : edges) {
        if (trusted_only && !e.trusted) continue;
        int next;
        if (e.from == at && !seen[e.to]) {
          next = e.to;
          poses[next] = poses[at] * e.measurement;
        } else if (e.to == at && !seen[e.from]) {
          next = e.from;
          poses[next] = poses[at] * e.measurement.inverse();
        } else {
          continue;
        }
        seen[next] = true;
        frontier.push(next);
      }
    }
  }
  return poses;
}

// Runs body(k) for k in [0, count) on `threads` threads, stopping early when it returns an error.
absl::Status ForEach(int count, int threads, const std::function<absl::Status(int)>& body) {
  std::atomic<int> next{0};
  std::mutex mutex;
  absl::Status first;
  const auto worker = [&] {
    for (int k = next++; k < count; k = next++) {
      absl::Status s = body(k);
      if (!s.ok()) {
        std::lock_guard<std::mutex> lock(mutex);
        if (first.ok()) first = s;
        next = count;
      }
    }
  };
  std::vector<std::thread> helpers;
  for (int t = 1; t < std::min(threads, count); ++t) helpers.emplace_back(worker);
  worker();
  for (std::thread& t : helpers) t.join();
  return first;
}

}  // namespace

absl::Status ValidateAlignOptions(int n, const AlignOptions& options) {
  if (n < 2) return absl::InvalidArgumentError(absl::StrCat("scans: need at least 2, got ", n));
  if (!options.initial_poses.empty() && static_cast<int>(options.initial_poses.size()) != n) {
    return absl::InvalidArgumentError(
        absl::StrCat("initial_poses: ", options.initial_poses.size(), " poses for ", n, " scans"));
  }
  for (std::size_t i = 0; i < options.initial_poses.size(); ++i) {
    if (absl::Status s =
            CheckRigid(options.initial_poses[i], absl::StrCat("initial_poses[", i, "]"));
        !s.ok()) {
      return s;
    }
  }
  if (options.anchor < 0 || options.anchor >= n) {
    return absl::InvalidArgumentError(
        absl::StrCat("anchor: ", options.anchor, " is not a scan index (0 .. ", n - 1, ")"));
  }
  if (!(options.min_overlap >= 0.0 && options.min_overlap <= 1.0)) {
    return absl::InvalidArgumentError("min_overlap: must be in [0, 1]");
  }
  const GivenLength& overlap = options.overlap_distance;
  if (!(overlap.value > 0.0 &&
        (overlap.absolute ? std::isfinite(overlap.value) : overlap.value <= 1000.0))) {
    return absl::InvalidArgumentError(overlap.absolute
                                          ? "overlap_distance: must be a positive length"
                                          : "overlap_distance_d: must be in (0, 1000]");
  }
  if (options.threads < 1) return absl::InvalidArgumentError("threads: must be >= 1");
  return ValidateOptions(options.edge);
}

std::string_view PairPolicyName(PairPolicy policy) { return NameOf(PairPolicyNames(), policy); }

const EnumNames& PairPolicyNames() {
  static constexpr EnumValueName kValues[] = {
      {static_cast<int>(PairPolicy::kSequential), "sequential", "SEQUENTIAL"},
      {static_cast<int>(PairPolicy::kLoop), "loop", "LOOP"},
      {static_cast<int>(PairPolicy::kOverlap), "overlap", "OVERLAP"},
  };
  static constexpr EnumNames kNames{"PairPolicy", "PAIR_POLICY_", kValues};
  return kNames;
}

absl::StatusOr<AlignResult> AlignScans(const std::vector<PointCloud>& scans,
                                       const AlignOptions& options,
                                       const AlignCallbacks& callbacks) {
  const auto start = std::chrono::steady_clock::now();
  const int n = static_cast<int>(scans.size());
  if (absl::Status s = ValidateAlignOptions(n, options); !s.ok()) return s;
  // Every scan as a target (index, normals, noise, MLS patches, samples), built once.
  std::vector<TargetPtr> targets(n);
  if (absl::Status s = ForEach(
          n, options.threads,
          [&](int i) -> absl::Status {
            auto built = Target::Build(scans[i], TargetOptions{}, callbacks.should_stop);
            if (!built.ok()) {
              return absl::Status(built.status().code(),
                                  absl::StrCat("scans[", i, "]: ", built.status().message()));
            }
            targets[i] = *std::move(built);
            return absl::OkStatus();
          });
      !s.ok()) {
    return s;
  }
  auto result = AlignTargets(targets, options, callbacks);
  if (result.ok()) {
    result->seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  return result;
}

absl::StatusOr<AlignResult> AlignTargets(const std::vector<std::shared_ptr<const Target>>& targets,
                                         const AlignOptions& options,
                                         const AlignCallbacks& callbacks) {
  const auto start = std::chrono::steady_clock::now();
  const int n = static_cast<int>(targets.size());
  if (absl::Status s = ValidateAlignOptions(n, options); !s.ok()) return s;
  for (int i = 0; i < n; ++i) {
    if (!targets[i]) return absl::InvalidArgumentError(absl::StrCat("scans[", i, "]: no target"));
  }
  const std::vector<Matrix4> initial = options.initial_poses.empty()
                                           ? std::vector<Matrix4>(n, Matrix4::Identity())
                                           : options.initial_poses;
  const auto stopped = [&] { return callbacks.should_stop && callbacks.should_stop(); };
  std::vector<Samples> samples(n);
  for (int i = 0; i < n; ++i) samples[i] = SamplesOf(*targets[i]);
  AlignResult result;
  for (const TargetPtr& t : targets) result.sampling_distance += t->sampling_distance() / n;
  const double d = result.sampling_distance;

  // 2. The pairs, and their graph must join every scan.
  std::vector<std::pair<int, int>> pairs = CandidatePairs(options.pairs, n);
  if (options.pairs == PairPolicy::kOverlap) {
    std::vector<std::pair<int, int>> overlapping;
    for (const auto& [i, j] : pairs) {
      const Matrix4 relative = initial[i].inverse() * initial[j];
      if (NearShare(*targets[i], samples[j].points, relative, options.overlap_distance.In(d)) >=
          options.min_overlap) {
        overlapping.emplace_back(i, j);
      }
    }
    pairs = std::move(overlapping);
  }
  {
    std::vector<PoseGraphEdge> graph;
    for (const auto& [i, j] : pairs) graph.push_back({.from = i, .to = j});
    std::vector<int> unreachable;
    if (!IsConnected(n, graph, nullptr, &unreachable)) {
      return absl::InvalidArgumentError(absl::StrCat(
          "pairs: the pair graph (", std::string(PairPolicyName(options.pairs)),
          ") does not join every scan: ", absl::StrJoin(unreachable, ", "),
          " not reached from scan 0",
          options.pairs == PairPolicy::kOverlap ? " (lower min_overlap or give initial poses)"
                                                : ""));
    }
  }
  if (stopped()) return absl::CancelledError("stopped before the pairwise registrations");

  // 3. The edges: pairwise registrations from the initial relative poses.
  result.edges.resize(pairs.size());
  std::mutex report_mutex;
  int done = 0;
  RegistrationCallbacks edge_callbacks;
  edge_callbacks.should_stop = callbacks.should_stop;
  if (absl::Status s = ForEach(
          static_cast<int>(pairs.size()), options.threads,
          [&](int k) -> absl::Status {
            const auto [i, j] = pairs[k];
            AlignEdge& edge = result.edges[k];
            edge.from = i;
            edge.to = j;
            auto registered =
                Register(*targets[i], targets[j]->cloud(), initial[i].inverse() * initial[j],
                         options.edge, edge_callbacks);
            if (!registered.ok()) {
              return absl::Status(
                  registered.status().code(),
                  absl::StrCat("edge (", i, ", ", j, "): ", registered.status().message()));
            }
            if (registered->termination == Termination::kCancelled) {
              return absl::CancelledError(
                  absl::StrCat("stopped while registering edge (", i, ", ", j, ")"));
            }
            edge.registration = *std::move(registered);
            edge.relative = edge.registration.transform;
            const VoxelCloud voxels = BuildVoxelCloud(
                targets[j]->points(), targets[i]->voxel_cloud().voxel, std::nullopt);
            const double d_i = targets[i]->sampling_distance();
            edge.verification = edge.registration.verification
                                    ? *edge.registration.verification
                                    : VerifyAlignment(*targets[i], voxels, edge.relative,
                                                      {targets[i]->noise().sigma_d * d_i,
                                                       targets[j]->noise().sigma_d * d_i});
            edge.overlap = edge.verification.explained_fraction;
            const Information info = EdgeInformation(*targets[i], samples[j], edge.relative, d);
            edge.information = info.matrix;
            edge.correspondences = info.correspondences;
            if (callbacks.on_edge) {
              std::lock_guard<std::mutex> lock(report_mutex);
              callbacks.on_edge(edge, ++done, static_cast<int>(pairs.size()));
            }
            return absl::OkStatus();
          });
      !s.ok()) {
    return s;
  }

  // 4. The pose graph, started from poses chained along trusted edges first.
  // Each edge weighs by its share of the correspondences: xi^T information xi is then the
  // mean squared displacement over its overlap (units of d^2) times its count over the mean.
  double mean_correspondences = 0.0;
  for (const AlignEdge& e : result.edges) mean_correspondences += e.correspondences;
  mean_correspondences = std::max(1.0, mean_correspondences / result.edges.size());
  std::vector<PoseGraphEdge> graph;
  for (const AlignEdge& e : result.edges) {
    // A registration that does not verify, or that found too few correspondences, is not
    // trusted.
    const bool trusted = e.verification.verified() &&
                         e.registration.termination != Termination::kTooFewCorrespondences;
    graph.push_back({e.from, e.to, e.relative,
                     e.information * (e.correspondences / mean_correspondences),
                     e.verification.pose_covariance, trusted});
  }
  result.chained_poses = ChainedPoses(n, options.anchor, graph);
  PoseGraphOptions graph_options = options.graph;
  graph_options.anchor = options.anchor;
  auto solved = OptimisePoseGraph(result.chained_poses, graph, graph_options);
  if (!solved.ok()) return solved.status();
  result.poses = solved->poses;
  result.graph_iterations = solved->iterations;
  result.covariance_weighted_edges = solved->covariance_weighted;
  result.pose_covariances = solved->pose_covariances;
  for (std::size_t e = 0; e < result.edges.size(); ++e) {
    result.edges[e].residual_before_d = solved->residual_before_d[e];
    result.edges[e].residual_after_d = solved->residual_after_d[e];
    result.edges[e].kept = solved->kept[e];
    result.edges[e].trusted = graph[e].trusted;
  }

  // 5. What the graph changed: drift of the chain, and the loop's closure.
  for (int i = 0; i < n; ++i) {
    result.chain_deviation_d.push_back(
        RmsDistanceBetween(targets[i]->points(), result.chained_poses[i], result.poses[i]) / d);
  }
  if (options.pairs == PairPolicy::kLoop && n > 2) {
    Matrix4 loop = Matrix4::Identity();
    for (const AlignEdge& e : result.edges) loop = loop * e.relative;  // (0,1) ... (n-1,0)
    result.loop_closure_rotation_deg = RotationDegrees(loop);
    result.loop_closure_error_d =
        RmsDistanceBetween(targets[0]->points(), loop, Matrix4::Identity()) / d;
    result.loop_closure_exceeded =
        result.loop_closure_rotation_deg > options.max_loop_closure_deg ||
        result.loop_closure_error_d > options.max_loop_closure_d;
  }
  // The scans a chain of trusted (verified) edges joins to the anchor.
  std::vector<char> supported(n, 0);
  supported[options.anchor] = 1;
  for (bool grew = true; grew;) {
    grew = false;
    for (const AlignEdge& e : result.edges) {
      if (!e.trusted || supported[e.from] == supported[e.to]) continue;
      supported[e.from] = supported[e.to] = 1;
      grew = true;
    }
  }
  for (int i = 0; i < n; ++i) {
    if (!supported[i]) result.unverified_scans.push_back(i);
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace mlsreg
