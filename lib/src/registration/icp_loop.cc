#include "icp_loop.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace mlsreg::internal {
namespace {

// Poses remembered to detect that ICP has stopped, or cycles through a few poses: hard filters
// can make it alternate between two or more poses forever.
constexpr std::size_t kCycleMemory = 8;
// Poses the noise-aware stall rule compares: a pose that settled into the noise's jitter stays
// there, so fewer than the cycle memory suffice.
constexpr std::size_t kNoiseStallWindow = 6;

// The largest distance between where `transform` and `pose` put the samples (`moved` =
// transform * samples), or a value >= limit as soon as one sample moves that far.
double MaxDisplacement(std::span<const Vec3> moved, const RigidTransform& transform,
                       const RigidTransform& pose, double limit) {
  const double limit_squared = limit * limit;
  const RigidTransform back = pose * transform.inverse(Eigen::Isometry);  // pose * p = back * y
  double worst = 0.0;
  for (const Vec3& y : moved) {
    worst = std::max(worst, (back * y - y).squaredNorm());
    if (worst >= limit_squared) break;
  }
  return std::sqrt(worst);
}

// True when the samples are within `threshold` of where one of the recent poses put them: no
// motion (the newest pose) or a cycle (an older one).
bool ReturnsToRecentPose(std::span<const Vec3> moved, const RigidTransform& transform,
                         std::span<const RigidTransform> recent, double threshold) {
  for (const RigidTransform& pose : recent) {
    if (MaxDisplacement(moved, transform, pose, threshold) < threshold) return true;
  }
  return false;
}

// True when the `window` most recent poses all lie within `band` of the current one: the pose
// only jitters (hard filters flipping a few correspondences back and forth on noisy data).
bool Stalled(std::span<const Vec3> moved, const RigidTransform& transform,
             std::span<const RigidTransform> recent, double band,
             std::size_t window = kCycleMemory) {
  if (band <= 0.0 || recent.size() < window) return false;
  for (const RigidTransform& pose : recent.first(window)) {
    if (MaxDisplacement(moved, transform, pose, band) >= band) return false;
  }
  return true;
}

// True when the `window` most recent poses all put the samples within an RMS distance of `band`
// of where `transform` puts them (`moved`).
bool StalledRms(std::span<const Vec3> moved, const RigidTransform& transform,
                std::span<const RigidTransform> recent, double band, std::size_t window) {
  if (!(band > 0.0) || recent.size() < window || moved.empty()) return false;
  const double limit = band * band * static_cast<double>(moved.size());
  for (const RigidTransform& pose : recent.first(window)) {
    const RigidTransform back = pose * transform.inverse(Eigen::Isometry);
    double sum = 0.0;
    for (const Vec3& y : moved) {
      sum += (back * y - y).squaredNorm();
      if (sum > limit) return false;
    }
  }
  return true;
}

// The largest motion of a sample under `increment` applied after `pose`.
double StepSize(std::span<const Vec3> samples, const RigidTransform& pose,
                const RigidTransform& increment) {
  double max_move = 0.0;
  for (const Vec3& s : samples) {
    const Vec3 x = pose * s;
    max_move = std::max(max_move, (increment * x - x).squaredNorm());
  }
  return std::sqrt(max_move);
}

}  // namespace

void RunIcpLoop(IcpStep& step, RigidTransform pose, const LoopSettings& settings,
                const RegistrationCallbacks& callbacks, Clock::time_point start,
                RegistrationResult& result) {
  const auto stop_requested = [&] { return callbacks.should_stop && callbacks.should_stop(); };
  // Poses before the most recent iterations of the current phase, newest first.
  std::vector<RigidTransform> recent_poses;
  recent_poses.reserve(kCycleMemory + 1);
  result.termination = Termination::kMaxIterations;
  for (int iteration = 1; iteration <= settings.max_iterations; ++iteration) {
    if (stop_requested()) {
      result.termination = Termination::kCancelled;
      break;
    }
    Clock::time_point phase = Clock::now();
    IterationReport report;
    report.iteration = settings.iteration_offset + iteration;
    if (!step.Match(pose, report) || stop_requested()) {
      result.termination = Termination::kCancelled;
      break;
    }
    result.timings.matching += Seconds(phase);

    bool converged = false;
    const bool enough = report.counts.matched >= settings.min_correspondences;
    if (enough) {
      phase = Clock::now();
      const bool coarse = step.coarse();
      recent_poses.insert(recent_poses.begin(), pose);
      if (recent_poses.size() > kCycleMemory) recent_poses.pop_back();
      if (const std::optional<RigidTransform> increment = step.Solve(report)) {
        const RigidTransform before = pose;
        pose = *increment * pose;
        const double threshold = coarse ? settings.coarse_convergence : settings.convergence;
        if (settings.rule == StopRule::kStepSize) {
          converged = StepSize(step.samples(), before, *increment) < threshold;
        } else {
          // The pose's standard error from this iteration's accepted residuals.
          const double standard_error =
              report.rmse / std::sqrt(static_cast<double>(report.counts.matched));
          converged =
              ReturnsToRecentPose(step.moved_samples(), pose, recent_poses, threshold) ||
              (!coarse && Stalled(step.moved_samples(), pose, recent_poses, settings.stall)) ||
              Stalled(step.moved_samples(), pose, recent_poses, settings.noise_stall,
                      kNoiseStallWindow) ||
              (!coarse &&
               StalledRms(step.moved_samples(), pose, recent_poses,
                          settings.stall_standard_errors * standard_error, kNoiseStallWindow));
        }
      }
      result.timings.optimisation += Seconds(phase);
    }

    result.iterations = iteration;  // of this run
    RecordIteration(result, report, pose, callbacks, start);
    if (!enough) {
      result.termination = Termination::kTooFewCorrespondences;
      break;
    }
    if (settings.reached && settings.reached(pose)) {
      result.termination = Termination::kConverged;
      result.converged = true;
      break;
    }
    if (converged && step.coarse()) {
      step.Refine();  // the finer correspondences get their own run to convergence
      recent_poses.clear();
      converged = false;
    }
    if (converged) {
      result.termination = Termination::kConverged;
      result.converged = true;
      break;
    }
  }
  result.transform = pose.matrix();
}

}  // namespace mlsreg::internal
