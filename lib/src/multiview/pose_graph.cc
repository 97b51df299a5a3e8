#include "mlsreg/multiview/pose_graph.h"

#include <ceres/ceres.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numeric>

#include "absl/strings/str_cat.h"

namespace mlsreg {
namespace {

// Residual of one edge: sqrt_information * xi, where exp(xi) = inv(P_from) P_to inv(Z).
struct EdgeCost {
  Eigen::Quaterniond z_inverse_q;
  Eigen::Vector3d z_inverse_t;
  Matrix6 sqrt_information;

  template <typename T>
  bool operator()(const T* q_from, const T* t_from, const T* q_to, const T* t_to,
                  T* residual) const {
    using Quaternion = Eigen::Quaternion<T>;
    using Vector3 = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Quaternion> qi(q_from), qj(q_to);
    const Eigen::Map<const Vector3> ti(t_from), tj(t_to);
    const Quaternion qi_inverse = qi.conjugate();
    const Quaternion q_relative = qi_inverse * qj;
    const Vector3 t_relative = qi_inverse * (tj - ti);
    Quaternion q_delta = q_relative * z_inverse_q.cast<T>();
    const Vector3 t_delta = t_relative + q_relative * z_inverse_t.cast<T>();
    if (q_delta.w() < T(0)) q_delta.coeffs() = -q_delta.coeffs();
    Eigen::Matrix<T, 6, 1> xi;
    xi << T(2) * q_delta.x(), T(2) * q_delta.y(), T(2) * q_delta.z(), t_delta;
    Eigen::Map<Eigen::Matrix<T, 6, 1>> r(residual);
    r = sqrt_information.cast<T>() * xi;
    return true;
  }
};

Matrix6 SqrtInformation(const Matrix6& information) {
  Matrix6 h = 0.5 * (information + information.transpose());
  h.diagonal().array() += 1e-9 * std::max(1.0, h.trace() / 6.0);  // sliding directions
  return Eigen::LLT<Matrix6>(h).matrixU();
}

struct PoseBlocks {
  std::vector<Eigen::Quaterniond> q;
  std::vector<Eigen::Vector3d> t;
  explicit PoseBlocks(const std::vector<Matrix4>& poses) {
    for (const Matrix4& p : poses) {
      q.emplace_back(Eigen::Matrix3d(p.topLeftCorner<3, 3>()));
      q.back().normalize();
      t.emplace_back(p.topRightCorner<3, 1>());
    }
  }
  std::vector<Matrix4> Poses() const {
    std::vector<Matrix4> out;
    for (std::size_t i = 0; i < q.size(); ++i) {
      Matrix4 m = Matrix4::Identity();
      m.topLeftCorner<3, 3>() = q[i].normalized().toRotationMatrix();
      m.topRightCorner<3, 1>() = t[i];
      out.push_back(m);
    }
    return out;
  }
};

// Each edge's information in a solve: `information`, or for the final solve its covariance's
// inverse (PoseGraphOptions::weigh_by_covariance). Only the edges in `use` are weighed.
struct EdgeWeights {
  std::vector<Matrix6> information;
  int covariance_weighted = 0;
};

EdgeWeights WeighEdges(const std::vector<PoseGraphEdge>& edges, const std::vector<bool>& use,
                       bool by_covariance) {
  EdgeWeights weights;
  for (const PoseGraphEdge& edge : edges) weights.information.push_back(edge.information);
  if (!by_covariance) return weights;
  // The covariance's inverse where it is positive definite, and for each such edge the scale
  // that makes `information` as strong: trace(covariance * scale * information) = 6.
  std::vector<std::optional<Matrix6>> inverse(edges.size());
  std::vector<double> scales;
  for (std::size_t e = 0; e < edges.size(); ++e) {
    if (!use[e] || !edges[e].covariance) continue;
    const Matrix6 c = 0.5 * (*edges[e].covariance + edges[e].covariance->transpose());
    const Eigen::LLT<Matrix6> llt(c);
    if (llt.info() != Eigen::Success) continue;
    inverse[e] = llt.solve(Matrix6::Identity());
    const double strength = (c * edges[e].information).trace();
    if (strength > 0.0) scales.push_back(6.0 / strength);
  }
  if (scales.empty()) return weights;
  std::nth_element(scales.begin(), scales.begin() + scales.size() / 2, scales.end());
  const double scale = scales[scales.size() / 2];
  for (std::size_t e = 0; e < edges.size(); ++e) {
    if (inverse[e]) {
      weights.information[e] = *inverse[e];
      ++weights.covariance_weighted;
    } else {
      weights.information[e] *= scale;
    }
  }
  return weights;
}

// The graph as a Ceres problem over `blocks`: one residual per edge in `use`, weighed by
// `information`, under a Cauchy loss when `robust`; the anchor's pose fixed.
void AddEdges(ceres::Problem& problem, PoseBlocks& blocks, const std::vector<PoseGraphEdge>& edges,
              const std::vector<Matrix6>& information, const std::vector<bool>& use,
              const PoseGraphOptions& options, bool robust) {
  for (std::size_t i = 0; i < blocks.q.size(); ++i) {
    problem.AddParameterBlock(blocks.q[i].coeffs().data(), 4, new ceres::EigenQuaternionManifold);
    problem.AddParameterBlock(blocks.t[i].data(), 3);
  }
  for (std::size_t e = 0; e < edges.size(); ++e) {
    if (!use[e]) continue;
    const PoseGraphEdge& edge = edges[e];
    const Matrix4 z_inverse = edge.measurement.inverse();
    auto* cost = new ceres::AutoDiffCostFunction<EdgeCost, 6, 4, 3, 4, 3>(new EdgeCost{
        Eigen::Quaterniond(Eigen::Matrix3d(z_inverse.topLeftCorner<3, 3>())).normalized(),
        z_inverse.topRightCorner<3, 1>(), SqrtInformation(information[e])});
    ceres::LossFunction* loss = robust ? new ceres::CauchyLoss(options.robust_scale_d) : nullptr;
    problem.AddResidualBlock(cost, loss, blocks.q[edge.from].coeffs().data(),
                             blocks.t[edge.from].data(), blocks.q[edge.to].coeffs().data(),
                             blocks.t[edge.to].data());
  }
  problem.SetParameterBlockConstant(blocks.q[options.anchor].coeffs().data());
  problem.SetParameterBlockConstant(blocks.t[options.anchor].data());
}

int Solve(ceres::Problem& problem, const PoseGraphOptions& options) {
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver.max_num_iterations = options.max_iterations;
  solver.num_threads = 1;
  solver.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  return static_cast<int>(summary.iterations.size());
}

int Solve(PoseBlocks& blocks, const std::vector<PoseGraphEdge>& edges,
          const std::vector<Matrix6>& information, const std::vector<bool>& use,
          const PoseGraphOptions& options, bool robust) {
  ceres::Problem problem;
  AddEdges(problem, blocks, edges, information, use, options, robust);
  return Solve(problem, options);
}

// Per pose, at the solution of `problem` (non-robust, its weights covariances' inverses): the
// covariance of (rotation vector, translation of the pose's origin) in the anchor's frame. Ceres'
// quaternion tangent delta turns by 2 |delta|. Empty for the anchor, and for every pose when the
// problem's Jacobian is rank deficient.
std::vector<std::optional<Matrix6>> PoseCovariances(ceres::Problem& problem, PoseBlocks& blocks,
                                                    int anchor) {
  const int n = static_cast<int>(blocks.q.size());
  std::vector<std::optional<Matrix6>> out(static_cast<std::size_t>(n));
  std::vector<std::pair<const double*, const double*>> pairs;
  for (int i = 0; i < n; ++i) {
    if (i == anchor) continue;
    const double* q = blocks.q[i].coeffs().data();
    const double* t = blocks.t[i].data();
    pairs.insert(pairs.end(), {{q, q}, {q, t}, {t, t}});
  }
  ceres::Covariance::Options options;
  options.num_threads = 1;
  ceres::Covariance covariance(options);
  if (pairs.empty() || !covariance.Compute(pairs, &problem)) return out;
  using Block = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;
  for (int i = 0; i < n; ++i) {
    if (i == anchor) continue;
    const double* q = blocks.q[i].coeffs().data();
    const double* t = blocks.t[i].data();
    Block qq, qt, tt;
    if (!covariance.GetCovarianceBlockInTangentSpace(q, q, qq.data()) ||
        !covariance.GetCovarianceBlockInTangentSpace(q, t, qt.data()) ||
        !covariance.GetCovarianceBlockInTangentSpace(t, t, tt.data())) {
      continue;
    }
    Matrix6 c;
    c << 4.0 * qq, 2.0 * qt, 2.0 * qt.transpose(), tt;
    out[static_cast<std::size_t>(i)] = 0.5 * (c + c.transpose());
  }
  return out;
}

// The poses' covariances at the final solution with each kept edge's information divided by
// its share of noise with the others, 1 + shared_scan_noise * (kept edges sharing one of its
// scans): the variance inflation of measurements that share part of their noise, which the
// solve, taking them as independent, counts once per edge (PoseGraphOptions). The poses are
// not solved again.
std::vector<std::optional<Matrix6>> SharedScanCovariances(PoseBlocks& blocks,
                                                          const std::vector<PoseGraphEdge>& edges,
                                                          std::vector<Matrix6> information,
                                                          const std::vector<bool>& use,
                                                          const PoseGraphOptions& options) {
  std::vector<int> degree(blocks.q.size(), 0);
  for (std::size_t e = 0; e < edges.size(); ++e) {
    if (!use[e]) continue;
    ++degree[edges[e].from];
    ++degree[edges[e].to];
  }
  for (std::size_t e = 0; e < edges.size(); ++e) {
    if (!use[e]) continue;
    const int sharing = degree[edges[e].from] + degree[edges[e].to] - 2;
    information[e] /= 1.0 + options.shared_scan_noise * sharing;
  }
  ceres::Problem problem;
  AddEdges(problem, blocks, edges, information, use, options, /*robust=*/false);
  return PoseCovariances(problem, blocks, options.anchor);
}

}  // namespace

PoseSigmas SigmasOf(const Matrix6& covariance) {
  const auto largest = [](const Eigen::Matrix3d& block) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(block, Eigen::EigenvaluesOnly);
    return std::sqrt(std::max(solver.eigenvalues().maxCoeff(), 0.0));
  };
  return {largest(covariance.topLeftCorner<3, 3>()) * 180.0 / M_PI,
          largest(covariance.bottomRightCorner<3, 3>())};
}

double EdgeResidual(const PoseGraphEdge& edge, const std::vector<Matrix4>& poses) {
  const PoseBlocks blocks(poses);
  const Matrix4 z_inverse = edge.measurement.inverse();
  const EdgeCost cost{
      Eigen::Quaterniond(Eigen::Matrix3d(z_inverse.topLeftCorner<3, 3>())).normalized(),
      z_inverse.topRightCorner<3, 1>(), SqrtInformation(edge.information)};
  Eigen::Matrix<double, 6, 1> r;
  cost(blocks.q[edge.from].coeffs().data(), blocks.t[edge.from].data(),
       blocks.q[edge.to].coeffs().data(), blocks.t[edge.to].data(), r.data());
  return r.norm();
}

bool IsConnected(int n, const std::vector<PoseGraphEdge>& edges, const std::vector<bool>* kept,
                 std::vector<int>* unreachable) {
  std::vector<int> parent(static_cast<std::size_t>(n));
  std::iota(parent.begin(), parent.end(), 0);
  const auto find = [&](int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (std::size_t e = 0; e < edges.size(); ++e) {
    if (kept && !(*kept)[e]) continue;
    parent[find(edges[e].from)] = find(edges[e].to);
  }
  bool connected = true;
  for (int i = 0; i < n; ++i) {
    if (find(i) != find(0)) {
      connected = false;
      if (unreachable) unreachable->push_back(i);
    }
  }
  return connected;
}

absl::StatusOr<PoseGraphResult> OptimisePoseGraph(const std::vector<Matrix4>& initial,
                                                  const std::vector<PoseGraphEdge>& edges,
                                                  const PoseGraphOptions& options) {
  const int n = static_cast<int>(initial.size());
  if (n < 1) return absl::InvalidArgumentError("poses: the graph has no poses");
  if (options.anchor < 0 || options.anchor >= n) {
    return absl::InvalidArgumentError(
        absl::StrCat("anchor: ", options.anchor, " is not a pose index (0 .. ", n - 1, ")"));
  }
  if (!(options.shared_scan_noise >= 0.0 && options.shared_scan_noise <= 1.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("shared_scan_noise: ", options.shared_scan_noise, " is not in [0, 1]"));
  }
  for (std::size_t e = 0; e < edges.size(); ++e) {
    const PoseGraphEdge& edge = edges[e];
    if (edge.from < 0 || edge.from >= n || edge.to < 0 || edge.to >= n || edge.from == edge.to) {
      return absl::InvalidArgumentError(
          absl::StrCat("edges[", e, "]: (", edge.from, ", ", edge.to, ") does not join two poses"));
    }
  }
  PoseGraphResult result;
  for (const PoseGraphEdge& edge : edges)
    result.residual_before_d.push_back(EdgeResidual(edge, initial));
  PoseBlocks blocks(initial);
  std::vector<bool> use(edges.size(), true);
  for (std::size_t e = 0; e < edges.size(); ++e) {
    if (edges[e].trusted) continue;
    use[e] = false;
    if (!IsConnected(n, edges, &use)) use[e] = true;
  }
  result.iterations += Solve(blocks, edges, WeighEdges(edges, use, false).information, use, options,
                             /*robust=*/true);
  // Drop the edges that still disagree, worst first, while the graph stays connected.
  std::vector<Matrix4> robust_poses = blocks.Poses();
  std::vector<std::size_t> order(edges.size());
  std::iota(order.begin(), order.end(), 0);
  std::vector<double> disagreement;
  for (const PoseGraphEdge& edge : edges) disagreement.push_back(EdgeResidual(edge, robust_poses));
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return disagreement[a] > disagreement[b]; });
  bool dropped = false;
  for (std::size_t e : order) {
    if (disagreement[e] <= options.reject_above_d) break;
    if (!use[e]) continue;
    use[e] = false;
    if (!IsConnected(n, edges, &use)) {
      use[e] = true;
    } else {
      dropped = true;
    }
  }
  // The final solve: plain least squares over the kept edges, from the robust solution.
  result.pose_covariances.assign(static_cast<std::size_t>(n), std::nullopt);
  if (dropped || !edges.empty()) {
    const EdgeWeights weights = WeighEdges(edges, use, options.weigh_by_covariance);
    result.covariance_weighted = weights.covariance_weighted;
    ceres::Problem problem;
    AddEdges(problem, blocks, edges, weights.information, use, options, /*robust=*/false);
    result.iterations += Solve(problem, options);
    // Weighed by covariances, the final solve's covariance is the poses' (in the edges' units),
    // once the noise that edges share through their scans is counted; weighed by information
    // alone it would be in units of d, and is not reported.
    if (weights.covariance_weighted > 0) {
      result.pose_covariances =
          SharedScanCovariances(blocks, edges, weights.information, use, options);
    }
  }
  result.poses = blocks.Poses();
  result.kept = use;
  for (const PoseGraphEdge& edge : edges) {
    result.residual_after_d.push_back(EdgeResidual(edge, result.poses));
  }
  return result;
}

}  // namespace mlsreg
