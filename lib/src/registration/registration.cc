// Register: validates the problem, checks the method's preconditions, and runs the method's row
// of the method table.
#include "mlsreg/registration/registration.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "coarse_alignment.h"
#include "method_runners.h"
#include "mlsreg/geometry/mls_radius.h"
#include "mlsreg/geometry/noise_estimate.h"
#include "mlsreg/registration/parameters.h"
#include "mlsreg/registration/verification.h"
#include "rival_search.h"

namespace mlsreg {

const EnumNames& TerminationNames() {
  static constexpr EnumValueName kValues[] = {
      {static_cast<int>(Termination::kConverged), "converged", "CONVERGED"},
      {static_cast<int>(Termination::kMaxIterations), "max_iterations", "MAX_ITERATIONS"},
      {static_cast<int>(Termination::kCancelled), "cancelled", "CANCELLED"},
      {static_cast<int>(Termination::kTooFewCorrespondences), "too_few_correspondences",
       "TOO_FEW_CORRESPONDENCES"},
  };
  static constexpr EnumNames kNames{"Termination", "TERMINATION_", kValues};
  return kNames;
}

std::string_view TerminationName(Termination termination) {
  return NameOf(TerminationNames(), termination);
}

const EnumNames& StageNames() {
  static constexpr EnumValueName kValues[] = {
      {static_cast<int>(Stage::kSingle), "single", "SINGLE"},
      {static_cast<int>(Stage::kStart), "start", "START"},
      {static_cast<int>(Stage::kGlobal), "global", "GLOBAL"},
      {static_cast<int>(Stage::kCandidate), "candidate", "CANDIDATE"},
      {static_cast<int>(Stage::kFinal), "final", "FINAL"},
      {static_cast<int>(Stage::kCoarse), "coarse", "COARSE"},
      {static_cast<int>(Stage::kFinish), "finish", "FINISH"},
      {static_cast<int>(Stage::kRival), "rival", "RIVAL"},
  };
  static constexpr EnumNames kNames{"Stage", "STAGE_", kValues};
  return kNames;
}

std::string_view StageName(Stage stage) { return NameOf(StageNames(), stage); }

const EnumNames& CandidateOriginNames() {
  static constexpr EnumValueName kValues[] = {
      {static_cast<int>(CandidateOrigin::kStart), "start", "START"},
      {static_cast<int>(CandidateOrigin::kGlobal), "global", "GLOBAL"},
      {static_cast<int>(CandidateOrigin::kDirect), "direct", "DIRECT"},
      {static_cast<int>(CandidateOrigin::kRival), "rival", "RIVAL"},
  };
  static constexpr EnumNames kNames{"CandidateOrigin", "CANDIDATE_ORIGIN_", kValues};
  return kNames;
}

std::string_view CandidateOriginName(CandidateOrigin origin) {
  return NameOf(CandidateOriginNames(), origin);
}

const EnumNames& FinishKindNames() {
  static constexpr EnumValueName kValues[] = {
      {static_cast<int>(FinishKind::kNone), "none", "NONE"},
      {static_cast<int>(FinishKind::kPlaneToPlane), "plane-to-plane", "PLANE_TO_PLANE"},
      {static_cast<int>(FinishKind::kMls), "mls", "MLS"},
  };
  static constexpr EnumNames kNames{"FinishKind", "FINISH_KIND_", kValues};
  return kNames;
}

std::string_view FinishKindName(FinishKind kind) { return NameOf(FinishKindNames(), kind); }

namespace {

// An automatic radius within kPatchRadiusTolerance of the one the target's patches were built
// at becomes that radius, so that matching uses the patches built with the target instead of
// building its own (a source whose noise estimate differs from the target's by a few percent
// would otherwise always miss them).
constexpr double kPatchRadiusTolerance = 0.1;

double SnapToTargetPatches(const Target& target, const RegistrationOptions& options,
                           double radius_d) {
  const MlsPatches* patches = target.mls_patches();
  if (!patches || options.mls.projection == MlsProjectionKind::kExact ||
      options.mls.polynomial_degree != patches->polynomial_degree() ||
      options.mls.max_iterations != patches->mls_options().max_iterations) {
    return radius_d;
  }
  const double patches_d = patches->radius() / target.sampling_distance();
  return std::abs(radius_d - patches_d) <= kPatchRadiusTolerance * patches_d ? patches_d : radius_d;
}

}  // namespace

namespace {

// The verdict on a method's result as method auto gives its own: the source's voxel samples at
// the target's working voxel scored, and a verified pose that few samples fix along one
// direction searched for a rival (rival_search.h) as far as `reach`. A stop asked for during the
// search cancels the result (no verdict).
void VerifyWithRivalSearch(const RegistrationProblem& problem, RegistrationResult& result,
                           internal::RivalReach reach) {
  const Target& target = *problem.target;
  VoxelCloud samples = BuildVoxelCloud(problem.source->points, target.voxel_cloud().voxel,
                                       problem.source->viewpoint, problem.threads);
  samples.sensor = problem.source_sensor;
  VerificationCaches caches;
  const auto verify = [&](const Matrix4& pose, const VerificationOptions& options) {
    return VerifyAlignment(target, samples, pose, problem.noise_levels, options, problem.threads,
                           &caches);
  };
  VerificationScore score = verify(result.transform, {});
  if (internal::SearchesForRival(score)) {
    const int iterations = result.iterations;
    const internal::RivalSearch search = internal::SearchRival(
        result.transform, score, samples, target.voxel_cloud().voxel,
        [&](const Matrix4& from, int k) {
          const RegistrationCallbacks callbacks =
              internal::StampedCallbacks(*problem.callbacks, Stage::kRival, k);
          RegistrationProblem aligned = problem;
          aligned.initial = from;
          aligned.callbacks = &callbacks;
          aligned.iteration_offset = iterations;
          RegistrationResult probe = internal::AlignVoxelClouds(
              aligned, target.voxel_cloud(), samples,
              internal::ScheduleFrom(target, samples, from,
                                     problem.options->automatic.candidate_iterations,
                                     problem.threads));
          internal::Stamp(probe, Stage::kRival, k);
          return probe;
        },
        verify, reach);
    if (search.cancelled) {
      result.termination = Termination::kCancelled;
      result.converged = false;
      return;
    }
    if (search.rival) {
      score.verdict = Verdict::kAmbiguous;
      result.rival = search.probes[*search.rival];
    }
  }
  result.verification = std::move(score);
}

}  // namespace

PoseVerdict VerifyPoseSearchingRivals(const Target& target, const PointCloud& source,
                                      const Matrix4& transform, int threads) {
  static const RegistrationOptions kDefaults;
  static const RegistrationCallbacks kNoCallbacks;
  const double d = target.sampling_distance();
  const SourceMeasures measured = MeasureSource(target, source, threads);
  RegistrationProblem problem{
      &target,    &source,       Orthonormalize(transform, Centroid(source.points)),
      &kDefaults, &kNoCallbacks, internal::Clock::now()};
  problem.threads = std::max(1, threads);
  problem.noise_levels = {target.noise().sigma_d * d, measured.noise_d * d};
  problem.source_sensor = measured.sensor;
  RegistrationResult result;
  result.transform = problem.initial;
  // A pose from anywhere: it may be an alias of the truth far along its weakest direction.
  VerifyWithRivalSearch(problem, result, internal::RivalReach::kFar);
  return {*std::move(result.verification), std::move(result.rival)};
}

absl::StatusOr<RegistrationResult> Register(const Target& target, const PointCloud& source,
                                            const Matrix4& initial,
                                            const RegistrationOptions& requested,
                                            const RegistrationCallbacks& callbacks,
                                            const ExecutionOptions& execution) {
  const internal::Clock::time_point start = internal::Clock::now();
  if (absl::Status s = ValidateOptions(requested); !s.ok()) return s;
  // Lengths given in metres become units of this target's d.
  const absl::StatusOr<RegistrationOptions> in_d =
      ResolveLengths(requested, target.sampling_distance());
  if (!in_d.ok()) return in_d.status();
  const RegistrationOptions& options = *in_d;
  if (absl::Status s = ValidatePointCloud(source, 3); !s.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("source: ", s.message()));
  }
  if (absl::Status s = CheckCoordinateRange(source); !s.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("source: ", s.message()));
  }
  if (absl::Status s = CheckRigid(initial, "initial_transform"); !s.ok()) return s;
  const MethodSpec& method = SpecOf(options.method);
  if (method.target == TargetRequirement::kOrganised && !target.grid()) {
    return OrganisedTargetRequired(options.method);
  }

  // The source's noise, estimated on the index the method then reuses: it sets an automatic MLS
  // radius (with the target's, estimated when it was built) and the verification's band.
  RegistrationOptions resolved = options;
  double noise_seconds = 0.0;
  std::optional<KdTree> source_tree;
  double source_noise_d = 0.0;
  std::optional<Vec3> source_sensor;
  const bool reads_mls = (method.parameter_groups & kMlsParameters) != 0;
  const bool auto_radius = reads_mls && !options.mls.radius_d;
  if (auto_radius || options.verify || options.method == Method::kAuto) {
    const internal::Clock::time_point phase = internal::Clock::now();
    source_tree.emplace(source.points, execution.threads);
    const NoiseEstimate noise =
        EstimateNoise(source.points, *source_tree, target.sampling_distance(), {}, {},
                      callbacks.should_stop, execution.threads);
    if (noise.stopped) {
      RegistrationResult cancelled =
          internal::CancelledBeforeIterations(initial, target.sampling_distance());
      cancelled.timings.total = internal::Seconds(start);
      return cancelled;
    }
    source_noise_d = noise.sigma_d;
    // Only the verdict asks where the source's sensor was.
    if (options.verify || options.method == Method::kAuto) {
      source_sensor = SourceSensor(target, source, *source_tree, execution.threads);
    }
    noise_seconds = internal::Seconds(phase);
  }
  if (auto_radius) {
    resolved.mls.radius_d = AutoMlsRadiusD(std::max(target.noise().sigma_d, source_noise_d));
    // Only methods that match by MLS use the patches (ST-SICP smooths by Algorithm 1).
    if (method.make_finder == &internal::MakeMlsFinder) {
      resolved.mls.radius_d = SnapToTargetPatches(target, options, *resolved.mls.radius_d);
    }
  }

  const double d = target.sampling_distance();
  // The start's rotation made exactly orthonormal about the source (Orthonormalize).
  RegistrationProblem problem{
      &target,   &source,    Orthonormalize(initial, Centroid(source.points)),
      &resolved, &callbacks, start};
  problem.source_tree = source_tree ? &*source_tree : nullptr;
  problem.noise_d = std::max(target.noise().sigma_d, source_noise_d);
  problem.noise_levels = {target.noise().sigma_d * d, source_noise_d * d};
  problem.noise = std::hypot(problem.noise_levels.target, problem.noise_levels.source);
  problem.threads = std::max(1, execution.threads);
  problem.source_sensor = source_sensor;
  absl::StatusOr<RegistrationResult> result = method.run(problem);
  if (!result.ok()) return result;
  result->timings.preprocessing += noise_seconds;
  result->target_noise_d = target.noise().sigma_d;
  result->source_noise_d = source_noise_d;
  if (reads_mls) {
    result->mls_radius_d = *resolved.mls.radius_d;
    result->mls_radius_auto = !options.mls.radius_d.has_value();
  }
  const CloudScales& scales = target.scales();
  result->scales.mean_spacing = d;
  result->scales.median_spacing = scales.median_spacing;
  result->scales.spacing_p90 = scales.spacing_p90;
  result->scales.extent = scales.extent;
  result->scales.working_voxel = scales.working_voxel;
  if (scales.sensor) result->scales.sensor = scales.sensor->position;
  if (reads_mls) result->scales.mls_radius = *resolved.mls.radius_d * d;
  for (const auto& [name, value] : requested.absolute_lengths) {
    result->scales.user_lengths.push_back({name, value, value / d});
  }
  if (options.verify && result->termination != Termination::kCancelled) {
    if (const std::optional<AutoReport>& report = result->auto_report) {
      result->verification = report->verification;
      if (report->rival) result->rival = report->candidates[*report->rival];
    } else {
      VerifyWithRivalSearch(problem, *result,
                            method.start_use == StartUse::kIgnores ? internal::RivalReach::kFar
                                                                   : internal::RivalReach::kNear);
    }
    if (result->verification) {
      result->scales.verification_band = result->verification->inlier_distance;
    }
  }
  result->timings.total = internal::Seconds(start);
  return result;
}

}  // namespace mlsreg
