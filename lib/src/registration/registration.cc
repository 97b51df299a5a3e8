#include "mlsreg/registration/registration.h"

#include <chrono>
#include <cmath>
#include <memory>

#include "absl/strings/str_cat.h"
#include "loop_support.h"
#include "mlsreg/correspondences/correspondence_finders.h"
#include "mlsreg/geometry/kd_tree.h"
#include "mlsreg/geometry/sampling.h"
#include "mlsreg/geometry/surface_analysis.h"
#include "mlsreg/registration/fast_global_registration.h"
#include "mlsreg/registration/generalized_icp.h"

namespace mlsreg {

std::string_view MethodName(Method method) {
  switch (method) {
    case Method::kCpSicp:
      return "cp-sicp";
    case Method::kMlsSicp:
      return "mls-sicp";
    case Method::kStSicp:
      return "st-sicp";
    case Method::kCpThenMlsSicp:
      return "cp-sicp+mls-sicp";
    case Method::kGicp:
      return "g-icp";
    case Method::kFgr:
      return "fgr";
    case Method::kRcBl:
      return "rc-bl";
    case Method::kRcP:
      return "rc-p";
  }
  return "unknown";
}

std::vector<Method> AllMethods() {
  return {Method::kCpSicp, Method::kMlsSicp, Method::kStSicp, Method::kCpThenMlsSicp,
          Method::kGicp,   Method::kFgr,     Method::kRcBl,   Method::kRcP};
}

absl::StatusOr<Method> ParseMethod(std::string_view name) {
  std::string known;
  for (Method m : AllMethods()) {
    if (name == MethodName(m)) return m;
    if (!known.empty()) known += ", ";
    known += MethodName(m);
  }
  return absl::InvalidArgumentError("method: unknown method '" + std::string(name) +
                                    "' (known: " + known + ")");
}

std::string_view CoarsePhaseFiltersName(CoarsePhaseFilters filters) {
  switch (filters) {
    case CoarsePhaseFilters::kNone:
      return "none";
    case CoarsePhaseFilters::kNormal:
      return "normal";
    case CoarsePhaseFilters::kAll:
      return "all";
  }
  return "unknown";
}

absl::StatusOr<CoarsePhaseFilters> ParseCoarsePhaseFilters(std::string_view name) {
  for (CoarsePhaseFilters f :
       {CoarsePhaseFilters::kNone, CoarsePhaseFilters::kNormal, CoarsePhaseFilters::kAll}) {
    if (name == CoarsePhaseFiltersName(f)) return f;
  }
  return absl::InvalidArgumentError("filter.coarse_phase: unknown value '" + std::string(name) +
                                    "' (known: all, normal, none)");
}

bool NeedsOrganisedTarget(Method method) {
  return method == Method::kRcBl || method == Method::kRcP;
}

absl::Status OrganisedTargetRequired(Method method) {
  return absl::FailedPreconditionError(
      "method " + std::string(MethodName(method)) +
      " needs an organised target with pinhole intrinsics (a depth image); this target "
      "has none (give the target file a .intrinsics sidecar, see depth_grid.h)");
}

std::string_view TerminationName(Termination termination) {
  switch (termination) {
    case Termination::kConverged:
      return "converged";
    case Termination::kMaxIterations:
      return "max_iterations";
    case Termination::kCancelled:
      return "cancelled";
    case Termination::kTooFewCorrespondences:
      return "too_few_correspondences";
  }
  return "unknown";
}

absl::Status ValidateOptions(const RegistrationOptions& o) {
  auto bad = [](const char* field, const char* rule) {
    return absl::InvalidArgumentError(absl::StrCat(field, " ", rule));
  };
  if (o.num_samples < 3 || o.num_samples > kMaxNumSamples) {
    return bad("num_samples", "must be in [3, 1000000]");
  }
  if (o.max_iterations < 1 || o.max_iterations > 100'000) {
    return bad("max_iterations", "must be in [1, 100000]");
  }
  if (!(o.convergence_d >= 0.0 && o.convergence_d <= 100.0)) {
    return bad("convergence_d", "must be in [0, 100]");
  }
  if (!(o.coarse_convergence_d >= 0.0 && o.coarse_convergence_d <= 100.0)) {
    return bad("coarse_convergence_d", "must be in [0, 100]");
  }
  if (!(o.stall_d >= 0.0 && o.stall_d <= 100.0)) return bad("stall_d", "must be in [0, 100]");
  if (!(o.tangential_damping >= 0.0 && o.tangential_damping <= 1e3)) {
    return bad("tangential_damping", "must be in [0, 1000]");
  }
  if (!(o.sicp_length_unit_d > 0.0 && o.sicp_length_unit_d <= 1e6)) {
    return bad("sicp_length_unit_d", "must be in (0, 1e6]");
  }
  if (!(o.mls.radius_d > 0.0 && o.mls.radius_d <= 100.0)) {
    return bad("mls.radius_d", "must be in (0, 100]");
  }
  if (o.mls.polynomial_degree < 0 || o.mls.polynomial_degree > 3) {
    return bad("mls.polynomial_degree", "must be in [0, 3]");
  }
  if (o.mls.max_iterations < 1 || o.mls.max_iterations > 1000) {
    return bad("mls.max_iterations", "must be in [1, 1000]");
  }
  if (!(o.filter.min_normal_dot >= -1.0 && o.filter.min_normal_dot <= 1.0)) {
    return bad("filter.min_normal_dot", "must be in [-1, 1]");
  }
  if (!(o.filter.min_curvature_ratio >= 0.0 && o.filter.min_curvature_ratio <= 1.0)) {
    return bad("filter.min_curvature_ratio", "must be in [0, 1]");
  }
  if (!(o.filter.max_distance_d >= 0.0 && std::isfinite(o.filter.max_distance_d))) {
    return bad("filter.max_distance_d", "must be >= 0 (0 disables)");
  }
  if (o.min_correspondences < 3) return bad("min_correspondences", "must be >= 3");
  if (o.gicp.covariance_neighbors < 3 || o.gicp.covariance_neighbors > 64) {
    return bad("gicp.covariance_neighbors", "must be in [3, 64]");
  }
  if (!(o.gicp.epsilon > 0.0 && o.gicp.epsilon <= 1.0)) {
    return bad("gicp.epsilon", "must be in (0, 1]");
  }
  if (!(o.gicp.max_distance_d > 0.0 && o.gicp.max_distance_d <= 1e6)) {
    return bad("gicp.max_distance_d", "must be in (0, 1e6]");
  }
  if (!(o.fgr.feature_radius_d > 0.0 && o.fgr.feature_radius_d <= kMaxFgrFeatureRadiusD)) {
    return bad("fgr.feature_radius_d", "must be in (0, 100]");
  }
  if (o.fgr.samples < 10 || o.fgr.samples > kMaxFgrSamples) {
    return bad("fgr.samples", "must be in [10, 10000]");
  }
  SparseIcpOptions sicp = o.sicp;
  sicp.length_unit = 1.0;  // derived; validated above
  return ValidateSparseIcpOptions(sicp);
}

namespace {

using internal::Clock;
using internal::Seconds;

// The source side of a registration: random samples with their local surface properties.
struct SourceSamples {
  std::vector<Vec3> points;
  SurfaceProperties surface;
};

std::unique_ptr<CorrespondenceFinder> MakeFinder(Method method, const Target& target,
                                                 const RegistrationOptions& options) {
  const double d = target.sampling_distance();
  switch (method) {
    case Method::kCpSicp:
    case Method::kStSicp:  // on the smoothed target
    case Method::kGicp:    // not used: G-ICP has its own loop
    case Method::kFgr:     // not used: FGR has its own loop
      return std::make_unique<ClosestPointFinder>(target);
    case Method::kRcBl:
      return std::make_unique<ReverseCalibrationFinder>(
          target, ReverseCalibrationFinder::Interpolation::kBilinear);
    case Method::kRcP:
      return std::make_unique<ReverseCalibrationFinder>(
          target, ReverseCalibrationFinder::Interpolation::kPhong);
    case Method::kCpThenMlsSicp:  // phases run as kCpSicp, then kMlsSicp
    case Method::kMlsSicp: {
      MlsOptions mls;
      mls.radius = options.mls.radius_d * d;
      mls.polynomial_degree = options.mls.polynomial_degree;
      mls.max_iterations = options.mls.max_iterations;
      return std::make_unique<MlsCorrespondenceFinder>(target, mls, options.mls.warm_start,
                                                       options.mls.far_queries);
    }
  }
  return nullptr;
}

// Poses remembered to detect that ICP has stopped, or cycles through a few poses: hard filters
// can make it alternate between two or more poses forever.
constexpr std::size_t kCycleMemory = 8;

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

// True when a full memory of recent poses all lie within `band` of the current one: the pose
// only jitters (hard filters flipping a few correspondences back and forth on noisy data).
bool Stalled(std::span<const Vec3> moved, const RigidTransform& transform,
             std::span<const RigidTransform> recent, double band) {
  if (band <= 0.0 || recent.size() < kCycleMemory) return false;
  for (const RigidTransform& pose : recent) {
    if (MaxDisplacement(moved, transform, pose, band) >= band) return false;
  }
  return true;
}

// Radius of the source's local analysis: the scale at which the target side's curvature is
// measured, so the curvature-ratio filter compares like with like.
double AnalysisRadius(Method method, const Target& target, const RegistrationOptions& options) {
  const double d = target.sampling_distance();
  return method == Method::kMlsSicp ? options.mls.radius_d * d
                                    : target.options().analysis_radius_d * d;
}

// The Sparse ICP loop with the correspondences of options.method. Inputs are validated by the
// caller; iteration numbers in reports start after `iteration_offset` and elapsed times count
// from `start`.
RegistrationResult RunSparseIcp(const Target& target, const PointCloud& source,
                                const Matrix4& initial, const RegistrationOptions& options,
                                const RegistrationCallbacks& callbacks, Clock::time_point start,
                                int iteration_offset) {
  RegistrationResult result;
  const double d = target.sampling_distance();
  result.sampling_distance = d;

  // Subsampling.
  Clock::time_point phase = Clock::now();
  const std::vector<std::uint32_t> indices =
      RandomSubsample(source.size(), static_cast<std::size_t>(options.num_samples), options.seed);
  SourceSamples samples;
  samples.points.reserve(indices.size());
  for (std::uint32_t i : indices) samples.points.push_back(source.points[i]);
  result.num_samples = static_cast<int>(indices.size());
  result.timings.subsampling = Seconds(phase);

  // Preprocessing: source normals and surface variation at the samples.
  phase = Clock::now();
  const KdTree source_tree(source.points);
  samples.surface =
      AnalyzeSurface(source.points, source_tree, AnalysisRadius(options.method, target, options),
                     source.viewpoint, indices, callbacks.should_stop);
  result.timings.preprocessing = Seconds(phase);
  RigidTransform transform(Orthonormalize(initial));
  if (samples.surface.stopped) {
    result.termination = Termination::kCancelled;
    result.transform = transform.matrix();
    result.timings.total = Seconds(start);
    return result;
  }

  std::unique_ptr<CorrespondenceFinder> finder = MakeFinder(options.method, target, options);
  finder->set_should_stop(callbacks.should_stop);
  CorrespondenceFilterOptions filter_options;
  filter_options.min_normal_dot = options.filter.min_normal_dot;
  filter_options.min_curvature_ratio = options.filter.min_curvature_ratio;
  if (options.filter.max_distance_d > 0.0) {
    filter_options.max_distance = options.filter.max_distance_d * d;
  }
  filter_options.source_oriented = samples.surface.oriented;
  filter_options.target_oriented = finder->oriented_normals();
  const CorrespondenceFilter fine_filter(filter_options);
  CorrespondenceFilterOptions coarse_options = filter_options;
  if (options.filter.coarse_phase != CoarsePhaseFilters::kAll) {
    coarse_options.min_curvature_ratio = 0.0;
  }
  if (options.filter.coarse_phase == CoarsePhaseFilters::kNone) {
    coarse_options.min_normal_dot = -1.0;
  }
  const CorrespondenceFilter coarse_filter(coarse_options);

  SparseIcpOptions sicp = options.sicp;
  sicp.length_unit = options.sicp_length_unit_d * d;
  sicp.stop = options.convergence_d / options.sicp_length_unit_d;
  // Sliding is damped once every partner is a foot point: not in a coarse phase, whose far
  // queries are seeded from target samples.
  const double damping = sicp.metric == SicpMetric::kPointToPlane && finder->foot_points()
                             ? options.tangential_damping
                             : 0.0;
  sicp.tangential_weight = finder->can_refine() ? 0.0 : damping;
  SparseIcpSolver solver(sicp);

  // Per-iteration buffers, allocated once.
  const std::size_t m = samples.points.size();
  std::vector<Vec3> moved(m), moved_normals(m), partner_points(m), partner_normals(m);
  std::vector<Correspondence> correspondences(m);
  std::vector<std::uint8_t> accepted(m);
  solver.Reset(m);

  // Poses after the most recent iterations of the current phase, newest first.
  std::vector<RigidTransform> recent_poses;
  recent_poses.reserve(kCycleMemory + 1);
  result.termination = Termination::kMaxIterations;
  for (int iteration = 1; iteration <= options.max_iterations; ++iteration) {
    if (callbacks.should_stop && callbacks.should_stop()) {
      result.termination = Termination::kCancelled;
      break;
    }
    phase = Clock::now();
    for (std::size_t i = 0; i < m; ++i) {
      moved[i] = transform * samples.points[i];
      moved_normals[i] = transform.linear() * samples.surface.normals[i];
    }
    finder->Find(moved, correspondences);
    if (callbacks.should_stop && callbacks.should_stop()) {  // Find may have stopped part-way
      result.termination = Termination::kCancelled;
      break;
    }
    IterationReport report;
    report.iteration = iteration_offset + iteration;
    const CorrespondenceFilter& filter = finder->can_refine() ? coarse_filter : fine_filter;
    report.counts = filter.Apply(moved, moved_normals, samples.surface.curvature,
                                 samples.surface.valid, correspondences, accepted);
    double sum_squared = 0.0;
    for (std::size_t i = 0; i < m; ++i) {
      partner_points[i] = correspondences[i].point;
      partner_normals[i] = correspondences[i].normal;
      if (accepted[i]) sum_squared += (moved[i] - partner_points[i]).squaredNorm();
    }
    internal::SetRmse(report, sum_squared, d);
    result.timings.matching += Seconds(phase);

    bool converged = false;
    if (report.counts.matched >= options.min_correspondences) {
      phase = Clock::now();
      recent_poses.insert(recent_poses.begin(), transform);
      if (recent_poses.size() > kCycleMemory) recent_poses.pop_back();
      const RigidTransform increment =
          solver.Step(moved, partner_points, partner_normals, accepted);
      transform = increment * transform;
      const double threshold =
          (finder->can_refine() ? options.coarse_convergence_d : options.convergence_d) * d;
      converged =
          ReturnsToRecentPose(moved, transform, recent_poses, threshold) ||
          (!finder->can_refine() && Stalled(moved, transform, recent_poses, options.stall_d * d));
      report.admm_iterations = solver.last_outer_iterations();
      result.timings.optimisation += Seconds(phase);
    }

    result.iterations = iteration;  // of this run
    internal::RecordIteration(result, report, transform, callbacks, start);
    if (report.counts.matched < options.min_correspondences) {
      result.termination = Termination::kTooFewCorrespondences;
      break;
    }
    if (converged && finder->can_refine()) {
      finder->Refine();  // the finer correspondences get their own run to convergence
      solver.set_tangential_weight(damping);
      recent_poses.clear();
      converged = false;
    }
    if (converged) {
      result.termination = Termination::kConverged;
      result.converged = true;
      break;
    }
  }
  result.transform = transform.matrix();
  result.timings.total = Seconds(start);
  return result;
}

// ST-SICP's target: every target sample projected onto the target's own MLS surface (de-noised;
// samples whose projection fails keep their position), prepared like any target but keeping the
// original surface variation for the curvature filter (see Target::WithMovedPoints). Asks
// `should_stop` (may be empty) every few thousand points, since a large target takes seconds;
// null when it said stop.
absl::StatusOr<std::shared_ptr<const Target>> SmoothedTarget(
    const Target& target, const RegistrationOptions& options,
    const std::function<bool()>& should_stop) {
  MlsOptions mls;
  mls.radius = options.mls.radius_d * target.sampling_distance();
  mls.polynomial_degree = options.mls.polynomial_degree;
  mls.max_iterations = options.mls.max_iterations;
  const MlsProjector projector(target.points(), target.tree(), mls);
  MlsProjector::Workspace workspace;
  std::vector<Vec3> smoothed;
  smoothed.reserve(target.points().size());
  StopPoller stop(should_stop, 64);
  for (const Vec3& p : target.points()) {
    if (stop.Poll()) return std::shared_ptr<const Target>();
    const MlsProjection projection = projector.Project(p, workspace);
    smoothed.push_back(projection.status == ProjectionStatus::kOk ? projection.point : p);
  }
  return target.WithMovedPoints(std::move(smoothed));
}

// Adds a later phase's result to an earlier one's: one trace, summed phase timings.
void AppendPhase(RegistrationResult& total, RegistrationResult&& phase) {
  total.transform = phase.transform;
  total.converged = phase.converged;
  total.termination = phase.termination;
  total.iterations += phase.iterations;
  for (IterationReport& r : phase.trace) total.trace.push_back(std::move(r));
  total.timings.preprocessing += phase.timings.preprocessing;
  total.timings.subsampling += phase.timings.subsampling;
  total.timings.matching += phase.timings.matching;
  total.timings.optimisation += phase.timings.optimisation;
}

}  // namespace

absl::StatusOr<RegistrationResult> Register(const Target& target, const PointCloud& source,
                                            const Matrix4& initial,
                                            const RegistrationOptions& options,
                                            const RegistrationCallbacks& callbacks) {
  const Clock::time_point start = Clock::now();
  if (absl::Status s = ValidateOptions(options); !s.ok()) return s;
  if (absl::Status s = ValidatePointCloud(source, 3); !s.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("source: ", s.message()));
  }
  if (absl::Status s = CheckCoordinateRange(source); !s.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("source: ", s.message()));
  }
  if (absl::Status s = CheckRigid(initial, "initial_transform"); !s.ok()) return s;

  RegistrationResult result;
  switch (options.method) {
    case Method::kCpSicp:
    case Method::kMlsSicp:
      result = RunSparseIcp(target, source, initial, options, callbacks, start, 0);
      break;
    case Method::kRcBl:
    case Method::kRcP:
      if (!target.grid()) return OrganisedTargetRequired(options.method);
      result = RunSparseIcp(target, source, initial, options, callbacks, start, 0);
      break;
    case Method::kStSicp: {
      const Clock::time_point phase = Clock::now();
      auto smoothed = SmoothedTarget(target, options, callbacks.should_stop);
      if (!smoothed.ok()) return smoothed.status();
      if (*smoothed == nullptr) {  // cancelled while smoothing: no iteration ran
        result.transform = Orthonormalize(initial).matrix();
        result.termination = Termination::kCancelled;
        result.sampling_distance = target.sampling_distance();
        result.timings.preprocessing = Seconds(phase);
        break;
      }
      const double smoothing = Seconds(phase);
      result = RunSparseIcp(**smoothed, source, initial, options, callbacks, start, 0);
      result.timings.preprocessing += smoothing;
      result.sampling_distance = target.sampling_distance();
      break;
    }
    case Method::kGicp:
      result = RunGeneralizedIcp(target, source, initial, options, callbacks, start);
      break;
    case Method::kFgr:
      result = RunFastGlobalRegistration(target, source, options, callbacks, start);
      break;
    case Method::kCpThenMlsSicp: {
      // Phase 1: CP-SICP to convergence without filtering (paper section 5.2.2).
      RegistrationOptions coarse = options;
      coarse.method = Method::kCpSicp;
      coarse.filter.min_normal_dot = -1.0;
      coarse.filter.min_curvature_ratio = 0.0;
      result = RunSparseIcp(target, source, initial, coarse, callbacks, start, 0);
      if (result.termination == Termination::kCancelled) break;
      // Phase 2: MLS-SICP from there.
      RegistrationOptions fine = options;
      fine.method = Method::kMlsSicp;
      AppendPhase(result, RunSparseIcp(target, source, result.transform, fine, callbacks, start,
                                       result.iterations));
      break;
    }
  }
  result.timings.total = Seconds(start);
  return result;
}

}  // namespace mlsreg
