#include "coarse_alignment.h"

#include <algorithm>
#include <cmath>

#include "gauss_newton_sums.h"
#include "icp_loop.h"
#include "mlsreg/core/parallel_for.h"
#include "mlsreg/core/parallel_sum.h"
#include "mlsreg/core/quantile.h"
#include "mlsreg/core/transform.h"
#include "mlsreg/geometry/neighbor_cache.h"
#include "mlsreg/solvers/rigid_motion.h"

namespace mlsreg::internal {
namespace {

// The start's capture range covers this share of the source's distances to the target: most
// of the misalignment, without the non-overlap's far tail.
constexpr double kStartCapturePercentile = 0.75;
// Geman-McClure scale per capture range.
constexpr double kKernelPerCapture = 1.0 / 3.0;

using Matrix6 = Eigen::Matrix<double, 6, 6>;
using Vector6 = Eigen::Matrix<double, 6, 1>;

class VoxelPlaneStep final : public IcpStep {
 public:
  VoxelPlaneStep(const VoxelCloud& target, const VoxelCloud& source, const CoarseSchedule& schedule,
                 double d, int threads)
      : target_(target),
        samples_(source.points),
        capture_(schedule.start_capture),
        final_capture_(schedule.final_capture),
        d_(d),
        threads_(threads),
        nearest_(source.points.size()),
        previous_(source.points.size(), Vec3::Zero()),
        samples_centre_(Centroid(samples_)) {}

  bool Match(const RigidTransform& pose, IterationReport& report) override {
    const double capture_squared = capture_ * capture_;
    const double kernel_squared = std::pow(kKernelPerCapture * capture_, 2);
    // The step turns the samples about their centroid (TwistIncrementAbout).
    centre_ = pose * samples_centre_;
    // Each sample's nearest voxel and its terms of the normal equations, on the threads, summed
    // in fixed blocks of samples (ParallelSum): the step is the same for any thread count.
    const GaussNewtonSums sums = ParallelSum(
        samples_.size(), threads_, partial_sums_,
        [&](std::size_t i, GaussNewtonSums& block) {
          const Vec3 previous = previous_[i];
          const Vec3 x = pose * samples_[i];
          previous_[i] = x;
          const Neighbor nn =
              TravellingNearest(*target_.tree, target_.points, x, previous, nearest_[i]);
          if (nn.distance_squared > capture_squared) {
            ++block.too_far;
            return;
          }
          if (!target_.valid[nn.index]) {
            ++block.invalid;
            return;
          }
          const Vec3& n = target_.normals[nn.index];
          const double r = n.dot(x - target_.points[nn.index]);
          const double k = kernel_squared / (kernel_squared + r * r);
          const double w = k * k;
          Vector6 j;
          j.head<3>() = (x - centre_).cross(n);
          j.tail<3>() = n;
          block.h.noalias() += w * j * j.transpose();
          block.g.noalias() += w * r * j;
          block.sum_squared += r * r;
          ++block.matched;
        },
        [](GaussNewtonSums& total, const GaussNewtonSums& block) { total.Add(block); });
    h_ = sums.h;
    g_ = sums.g;
    sums.Report(report, d_);
    return true;
  }

  std::optional<RigidTransform> Solve(IterationReport&) override {
    const Vector6 delta = SolveConstrainedStep(h_, -g_);
    if (!delta.allFinite()) return std::nullopt;
    return TwistIncrementAbout(delta, centre_);
  }

  std::span<const Vec3> moved_samples() const override { return {}; }  // kStepSize rule only
  std::span<const Vec3> samples() const override { return samples_; }
  bool coarse() const override { return capture_ > final_capture_; }
  void Refine() override { capture_ = std::max(final_capture_, 0.5 * capture_); }
  double capture() const { return capture_; }

 private:
  const VoxelCloud& target_;
  const std::vector<Vec3>& samples_;
  double capture_, final_capture_;
  double d_;
  int threads_;
  // Per sample: the target voxels nearest its last position (an iteration moves it by little).
  std::vector<NeighborCache<8>> nearest_;
  std::vector<Vec3> previous_;                 // per sample, where the last iteration put it
  std::vector<GaussNewtonSums> partial_sums_;  // per block of samples (ParallelSum)
  Vec3 samples_centre_;                        // the samples' centroid in the source's frame
  Vec3 centre_ = Vec3::Zero();                 // and where the last Match's pose put it
  Matrix6 h_;
  Vector6 g_;
};

}  // namespace

double StartCapture(const VoxelCloud& target, const VoxelCloud& source, const Matrix4& initial,
                    double final_capture, double target_extent, int threads) {
  if (source.points.empty() || target.points.empty()) return final_capture;
  const RigidTransform pose(Orthonormalize(initial));
  std::vector<double> distances(source.points.size());
  ParallelFor(
      source.points.size(), threads,
      [&](std::size_t begin, std::size_t end, int) {
        for (std::size_t i = begin; i < end; ++i) {
          distances[i] = std::sqrt(target.tree->Nearest(pose * source.points[i]).distance_squared);
        }
      },
      256);
  return std::clamp(QuantileInPlace(distances, kStartCapturePercentile), final_capture,
                    std::max(final_capture, 0.5 * target_extent));
}

CoarseSchedule ScheduleFrom(const Target& target, const VoxelCloud& source, const Matrix4& start,
                            int max_iterations, int threads) {
  const VoxelCloud& voxels = target.voxel_cloud();
  CoarseSchedule schedule;
  schedule.final_capture = kFinalCaptureVoxels * voxels.voxel;
  schedule.start_capture =
      StartCapture(voxels, source, start, schedule.final_capture, target.scales().extent, threads);
  schedule.convergence = kCoarseConvergenceVoxels * voxels.voxel;
  schedule.max_iterations = max_iterations;
  return schedule;
}

RegistrationResult AlignVoxelClouds(const RegistrationProblem& problem, const VoxelCloud& target,
                                    const VoxelCloud& source, const CoarseSchedule& schedule) {
  RegistrationResult result;
  result.sampling_distance = problem.target->sampling_distance();
  result.num_samples = static_cast<int>(source.size());
  VoxelPlaneStep step(target, source, schedule, result.sampling_distance, problem.threads);
  LoopSettings settings;
  settings.rule = StopRule::kStepSize;
  settings.max_iterations = schedule.max_iterations;
  settings.min_correspondences = problem.options->min_correspondences;
  settings.convergence = schedule.convergence;
  settings.coarse_convergence = schedule.convergence;
  settings.iteration_offset = problem.iteration_offset;
  settings.reached = schedule.reached;
  RunIcpLoop(step, RigidTransform(Orthonormalize(problem.initial)), settings, *problem.callbacks,
             problem.start, result);
  result.timings.total = Seconds(problem.start);
  return result;
}

}  // namespace mlsreg::internal
