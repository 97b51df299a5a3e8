#include "coarse_alignment.h"

#include <algorithm>
#include <cmath>

#include "icp_loop.h"
#include "mlsreg/core/parallel_for.h"
#include "mlsreg/core/quantile.h"
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
        matches_(source.points.size()) {}

  bool Match(const RigidTransform& pose, IterationReport& report) override {
    h_.setZero();
    g_.setZero();
    const double capture_squared = capture_ * capture_;
    const double kernel_squared = std::pow(kKernelPerCapture * capture_, 2);
    // The samples' nearest voxels in parallel; their sums in sample order, so that the step is
    // the same for any thread count.
    ParallelFor(
        samples_.size(), threads_,
        [&](std::size_t begin, std::size_t end, int) {
          for (std::size_t i = begin; i < end; ++i) {
            SampleMatch& m = matches_[i];
            const Vec3 previous = m.x;
            m.x = pose * samples_[i];
            const Neighbor nn =
                TravellingNearest(*target_.tree, target_.points, m.x, previous, nearest_[i]);
            m.kind = nn.distance_squared > capture_squared ? SampleMatch::kFar
                     : !target_.valid[nn.index]            ? SampleMatch::kInvalid
                                                           : SampleMatch::kMatched;
            m.voxel = nn.index;
          }
        },
        256);
    double sum_squared = 0.0;
    for (const SampleMatch& m : matches_) {
      if (m.kind == SampleMatch::kFar) {
        ++report.counts.rejected_distance;
        continue;
      }
      if (m.kind == SampleMatch::kInvalid) {
        ++report.counts.invalid;
        continue;
      }
      const Vec3& x = m.x;
      const Vec3& n = target_.normals[m.voxel];
      const double r = n.dot(x - target_.points[m.voxel]);
      const double k = kernel_squared / (kernel_squared + r * r);
      const double w = k * k;
      Vector6 j;
      j.head<3>() = x.cross(n);
      j.tail<3>() = n;
      h_.noalias() += w * j * j.transpose();
      g_.noalias() += w * r * j;
      sum_squared += r * r;
      ++report.counts.matched;
    }
    SetRmse(report, sum_squared, d_);
    return true;
  }

  std::optional<RigidTransform> Solve(IterationReport&) override {
    const Vector6 delta = SolveConstrainedStep(h_, -g_);
    if (!delta.allFinite()) return std::nullopt;
    return TwistIncrement(delta);
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
  // One sample's match in this iteration.
  struct SampleMatch {
    enum Kind : std::uint8_t { kFar, kInvalid, kMatched };
    Vec3 x = Vec3::Zero();
    std::uint32_t voxel = 0;
    Kind kind = kFar;
  };

  double d_;
  int threads_;
  // Per sample: the target voxels nearest its last position (an iteration moves it by little).
  std::vector<NeighborCache<8>> nearest_;
  std::vector<SampleMatch> matches_;
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
