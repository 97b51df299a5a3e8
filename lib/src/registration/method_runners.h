// The runners of the method table (method_table.cc): one registration problem in, a result out.
// Inputs are validated by Register before a runner is called.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "loop_support.h"
#include "mlsreg/core/point_cloud.h"
#include "mlsreg/correspondences/correspondence.h"
#include "mlsreg/geometry/kd_tree.h"
#include "mlsreg/geometry/surface_cache.h"
#include "mlsreg/geometry/target.h"
#include "mlsreg/registration/method.h"
#include "mlsreg/registration/options.h"
#include "mlsreg/registration/result.h"
#include "mlsreg/registration/verification.h"

namespace mlsreg {

// Pointers, never null, so that a composite method can pose a phase as a changed copy.
struct RegistrationProblem {
  const Target* target;
  const PointCloud* source;
  Matrix4 initial;
  const RegistrationOptions* options;
  const RegistrationCallbacks* callbacks;
  internal::Clock::time_point start;
  int iteration_offset = 0;             // iterations of earlier phases (composite methods)
  const KdTree* source_tree = nullptr;  // the source's index when Register built one already
  // The source's surface properties analysed so far, shared by the phases of a composite
  // method (auto's refinements and finish); null: each phase analyses its own samples.
  SurfaceCache* source_surface = nullptr;
  int threads = 1;       // ExecutionOptions::threads
  double noise_d = 0.0;  // the clouds' estimated noise (the larger), units of d; 0: unknown
  double noise = 0.0;    // their combined noise sigma, absolute; 0: unknown
  NoiseLevels noise_levels = {};  // each cloud's, absolute
  // The source's sensor (FindScanSensor), looked for when the target's is known; the
  // verification's samples carry it.
  std::optional<Vec3> source_sensor = {};
  // Sparse ICP from a pose that already verified (auto's finish): the samples whose first
  // correspondence the filter rejects are not matched again, and count in every later iteration
  // as they did then. Near a verified pose a sample outside the overlap, or on surface the
  // curvature test refuses, stays so; on KITTI these are three quarters of the finish's samples.
  bool drop_first_rejections = false;
};

namespace internal {

// The source's random samples (result.num_samples and timings.subsampling are set).
struct SourceSamples {
  std::vector<std::uint32_t> indices;
  std::vector<Vec3> points;
};
SourceSamples SubsampleSource(const PointCloud& source, const RegistrationOptions& options,
                              RegistrationResult& result);

// The result of a registration stopped before its first iteration: the start pose, cancelled.
// Register sets the total time.
inline RegistrationResult CancelledBeforeIterations(const Matrix4& initial, double d) {
  RegistrationResult result;
  result.transform = Orthonormalize(initial).matrix();
  result.termination = Termination::kCancelled;
  result.sampling_distance = d;
  return result;
}

// `phase`, run after `total`, appended to it: pose, termination, iterations, trace and timings.
void AppendPhase(RegistrationResult& total, RegistrationResult&& phase);

// Correspondence policies (MethodSpec::make_finder).
std::unique_ptr<CorrespondenceFinder> MakeClosestPointFinder(const Target& target,
                                                             const RegistrationOptions& options);
std::unique_ptr<CorrespondenceFinder> MakeMlsFinder(const Target& target,
                                                    const RegistrationOptions& options);
std::unique_ptr<CorrespondenceFinder> MakeBilinearFinder(const Target& target,
                                                         const RegistrationOptions& options);
std::unique_ptr<CorrespondenceFinder> MakePhongFinder(const Target& target,
                                                      const RegistrationOptions& options);

// Sparse ICP with the correspondences of problem.options.method (CP-SICP, MLS-SICP, RC-*).
absl::StatusOr<RegistrationResult> RunSparseIcp(const RegistrationProblem& problem);
// ST-SICP: CP-SICP on the target smoothed onto its own MLS surface.
absl::StatusOr<RegistrationResult> RunSmoothedTargetSicp(const RegistrationProblem& problem);
// CP-SICP+MLS-SICP: unfiltered CP-SICP to convergence, then MLS-SICP from there.
absl::StatusOr<RegistrationResult> RunCpThenMlsSicp(const RegistrationProblem& problem);
absl::StatusOr<RegistrationResult> RunGeneralizedIcp(const RegistrationProblem& problem);
// G-ICP's plane-to-plane step with each pair gated by its target point's neighbourhood (the
// points that defined its plane) instead of gicp.max_distance_d: auto's finish on clean data.
absl::StatusOr<RegistrationResult> RunPlaneToPlaneFinish(const RegistrationProblem& problem);
absl::StatusOr<RegistrationResult> RunFastGlobalRegistration(const RegistrationProblem& problem);
// auto: MLS-SICP from the start, else from global candidates, chosen by verification.
absl::StatusOr<RegistrationResult> RunAuto(const RegistrationProblem& problem);

}  // namespace internal
}  // namespace mlsreg
