// Coarse alignment: robust point-to-plane ICP between two voxel clouds (geometry/voxel_cloud.h)
// at the working resolution, with a capture range that follows the remaining misalignment:
// it starts from what the start pose leaves between the clouds and halves at every convergence
// down to a few voxels (multi-scale ICP, each level a coarse phase of the shared ICP loop).
// Residuals are weighted by Geman-McClure with a scale of a third of the capture range (as
// KISS-ICP ties its kernel to its threshold), so moving objects and non-overlap pull little.
#pragma once

#include <functional>

#include "method_runners.h"
#include "mlsreg/geometry/voxel_cloud.h"
#include "mlsreg/solvers/rigid_motion.h"

namespace mlsreg::internal {

struct CoarseSchedule {
  double start_capture = 0.0;  // the first capture range (absolute)
  double final_capture = 0.0;  // the last
  double convergence = 0.0;    // a level ends when no sample moves more than this
  int max_iterations = 60;     // over all levels
  // Ends the alignment early, converged, once its pose satisfies this (LoopSettings::reached).
  std::function<bool(const RigidTransform&)> reached;
};

// Coarse alignment ends at a capture range of this many working voxels, and a level converges
// when no voxel moves more than this share of a voxel.
inline constexpr double kFinalCaptureVoxels = 2.0;
inline constexpr double kCoarseConvergenceVoxels = 0.02;

// Samples of the start pose: the capture range a coarse alignment from `initial` starts with,
// kStartCapturePercentile of the source voxels' distances to the target's voxel cloud, at least
// `final_capture` and at most half the target's extent.
double StartCapture(const VoxelCloud& target, const VoxelCloud& source, const Matrix4& initial,
                    double final_capture, double target_extent, int threads = 1);

// The schedule of an alignment of `source` (the source's voxel cloud at the target's working
// voxel) from `start` to `target`'s voxel cloud: the capture range from what `start` leaves
// between them (StartCapture) down to kFinalCaptureVoxels, at most `max_iterations`.
CoarseSchedule ScheduleFrom(const Target& target, const VoxelCloud& source, const Matrix4& start,
                            int max_iterations, int threads);

// Aligns `source` (a voxel cloud of the problem's source) to `target` from problem.initial.
// Iterations are reported through problem.callbacks and appended to the result's trace.
RegistrationResult AlignVoxelClouds(const RegistrationProblem& problem, const VoxelCloud& target,
                                    const VoxelCloud& source, const CoarseSchedule& schedule);

}  // namespace mlsreg::internal
