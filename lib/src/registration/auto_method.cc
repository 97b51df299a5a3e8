// Method auto: registration from any start. MLS-SICP runs from the caller's start; when its
// result does not verify against the target's MLS surface, global candidates from FPFH matches
// are refined cheaply by MLS-SICP, the best verified one is refined fully, and the result says
// whether it verified.
#include <algorithm>
#include <cmath>
#include <optional>

#include "method_runners.h"
#include "mlsreg/geometry/feature_cloud.h"
#include "mlsreg/registration/global_candidates.h"
#include "mlsreg/registration/verification.h"

namespace mlsreg::internal {
namespace {

// Two scores whose inlier fractions differ by less than this are ranked by their RMSE.
constexpr double kFractionTie = 0.02;
// RANSAC's inlier distance: Open3D's 1.5 voxels, or 3 noise sigmas when that is larger.
constexpr double kInlierDistancePerVoxel = 1.5;
constexpr double kInlierDistancePerNoise = 3.0;

bool Better(const VerificationScore& a, const VerificationScore& b) {
  if (std::abs(a.inlier_fraction - b.inlier_fraction) >= kFractionTie) {
    return a.inlier_fraction > b.inlier_fraction;
  }
  return a.rmse_d < b.rmse_d;
}

// The caller's callbacks with every report stamped with its stage and candidate.
RegistrationCallbacks StampedCallbacks(const RegistrationCallbacks& callbacks, Stage stage,
                                       int candidate) {
  RegistrationCallbacks out;
  out.should_stop = callbacks.should_stop;
  if (callbacks.on_iteration) {
    out.on_iteration = [&callbacks, stage, candidate](const IterationReport& report) {
      IterationReport stamped = report;
      stamped.stage = stage;
      stamped.candidate = candidate;
      callbacks.on_iteration(stamped);
    };
  }
  return out;
}

class AutoRegistration {
 public:
  explicit AutoRegistration(const RegistrationProblem& problem)
      : problem_(problem),
        target_(*problem.target),
        params_(problem.options->automatic),
        d_(problem.target->sampling_distance()) {
    full_ = *problem.options;
    full_.method = Method::kMlsSicp;
    cheap_ = full_;
    cheap_.max_iterations = params_.candidate_iterations;
    cheap_.mls.projection = MlsProjectionKind::kPatches;
    base_ = problem;
    if (!base_.source_tree) {
      own_source_tree_.emplace(problem.source->points);
      base_.source_tree = &*own_source_tree_;
    }
  }

  absl::StatusOr<RegistrationResult> Run() {
    // Stage 1: MLS-SICP from the caller's start.
    Clock::time_point phase = Clock::now();
    absl::StatusOr<RegistrationResult> start = Refine(problem_.initial, full_, Stage::kStart, 0, 0);
    if (!start.ok() || start->termination == Termination::kCancelled) return Finish(start);
    const FeatureScale scale =
        target_.features() ? target_.features()->scale : ChooseFeatureScale(target_.points(), d_);
    samples_ =
        SampleOrientedPoints(problem_.source->points, *base_.source_tree, nullptr,
                             target_.options().analysis_radius_d * d_, problem_.source->viewpoint,
                             scale, problem_.callbacks->should_stop);
    if (!samples_) return Cancelled(*std::move(start));
    report_.candidates.push_back({CandidateOrigin::kStart, problem_.initial, start->transform, 0,
                                  start->iterations, Verify(start->transform), Seconds(phase)});
    report_.timings.start = Seconds(phase);
    if (report_.candidates[0].score.inlier_fraction >= params_.accept_fraction) {
      report_.early_exit = true;
      return Finish(start);
    }

    // Stage 2: global candidates from feature matches.
    phase = Clock::now();
    const StopCheck& should_stop = problem_.callbacks->should_stop;
    if (!ComputeFeatures(*samples_, should_stop)) return Cancelled(*std::move(start));
    const FeatureCloud* target_features = target_.features();
    std::optional<FeatureCloud> own_target_features;
    if (!target_features) {  // a target built without them
      own_target_features = BuildFeatureCloud(target_.points(), target_.tree(), &target_.surface(),
                                              0.0, target_.cloud().viewpoint, scale, should_stop);
      if (!own_target_features) return Cancelled(*std::move(start));
      target_features = &*own_target_features;
    }
    GlobalCandidateOptions global_options;
    global_options.max_candidates = params_.candidates;
    global_options.inlier_distance = std::max(kInlierDistancePerVoxel * scale.voxel,
                                              kInlierDistancePerNoise * problem_.noise_d * d_);
    global_options.seed = problem_.options->seed;
    const GlobalCandidates global =
        FindGlobalCandidates(*samples_, *target_features, global_options, should_stop);
    if (global.stopped) return Cancelled(*std::move(start));
    report_.feature_matches = global.matches;
    report_.timings.global = Seconds(phase);
    ReportGlobalStage(global);

    // Stage 3: each candidate refined cheaply and verified; the start competes with its result.
    phase = Clock::now();
    std::vector<RegistrationResult> refined;
    for (std::size_t k = 0; k < global.candidates.size(); ++k) {
      const Clock::time_point t = Clock::now();
      const int index = static_cast<int>(k) + 1;
      absl::StatusOr<RegistrationResult> r =
          Refine(global.candidates[k].transform, cheap_, Stage::kCandidate, index, 0);
      if (!r.ok()) return r.status();
      if (r->termination == Termination::kCancelled) return Cancelled(*std::move(start));
      report_.candidates.push_back({CandidateOrigin::kGlobal, global.candidates[k].transform,
                                    r->transform, global.candidates[k].inliers, r->iterations,
                                    Verify(r->transform), Seconds(t)});
      refined.push_back(*std::move(r));
    }
    report_.timings.candidates = Seconds(phase);
    int best = 0;
    for (int k = 1; k < static_cast<int>(report_.candidates.size()); ++k) {
      if (Better(report_.candidates[k].score, report_.candidates[best].score)) best = k;
    }
    report_.chosen = best;
    if (best == 0) return Finish(start);

    // Stage 4: the winner refined fully (MLS-SICP with every default) from its cheap result.
    phase = Clock::now();
    RegistrationResult winner = std::move(refined[best - 1]);
    absl::StatusOr<RegistrationResult> fine =
        Refine(winner.transform, full_, Stage::kFinal, best, winner.iterations);
    if (!fine.ok()) return fine.status();
    AppendPhase(winner, *std::move(fine));
    report_.timings.final = Seconds(phase);
    return Finish(std::move(winner));
  }

 private:
  absl::StatusOr<RegistrationResult> Refine(const Matrix4& start,
                                            const RegistrationOptions& options, Stage stage,
                                            int candidate, int iteration_offset) {
    const RegistrationCallbacks callbacks = StampedCallbacks(*problem_.callbacks, stage, candidate);
    RegistrationProblem problem = base_;
    problem.initial = start;
    problem.options = &options;
    problem.callbacks = &callbacks;
    problem.iteration_offset = iteration_offset;
    absl::StatusOr<RegistrationResult> result = RunSparseIcp(problem);
    if (result.ok()) {
      for (IterationReport& report : result->trace) {
        report.stage = stage;
        report.candidate = candidate;
      }
    }
    return result;
  }

  VerificationScore Verify(const Matrix4& transform) const {
    return VerifyAlignment(target_, samples_->points, samples_->normals, samples_->oriented,
                           transform, problem_.noise_d);
  }

  // One report for the global stage (iteration 0): the best candidate's pose.
  void ReportGlobalStage(const GlobalCandidates& global) const {
    if (!problem_.callbacks->on_iteration) return;
    IterationReport report;
    report.stage = Stage::kGlobal;
    report.transform =
        global.candidates.empty() ? problem_.initial : global.candidates.front().transform;
    report.counts.matched = global.matches;
    report.elapsed_seconds = Seconds(problem_.start);
    problem_.callbacks->on_iteration(report);
  }

  absl::StatusOr<RegistrationResult> Cancelled(RegistrationResult result) {
    result.termination = Termination::kCancelled;
    result.converged = false;
    return Finish(std::move(result));
  }

  absl::StatusOr<RegistrationResult> Finish(absl::StatusOr<RegistrationResult> result) {
    if (!result.ok()) return result;
    if (!report_.candidates.empty() && result->termination != Termination::kCancelled) {
      const AutoCandidate& chosen = report_.candidates[report_.chosen];
      report_.verification = report_.chosen == 0 ? chosen.score : Verify(result->transform);
      report_.verified = IsVerified(report_.verification, params_.verified_fraction);
    }
    result->auto_report = std::move(report_);
    return result;
  }

  const RegistrationProblem& problem_;
  const Target& target_;
  const AutoParams& params_;
  const double d_;
  RegistrationOptions full_, cheap_;
  RegistrationProblem base_;
  std::optional<KdTree> own_source_tree_;
  std::optional<FeatureCloud> samples_;
  AutoReport report_;
};

}  // namespace

absl::StatusOr<RegistrationResult> RunAuto(const RegistrationProblem& problem) {
  return AutoRegistration(problem).Run();
}

}  // namespace mlsreg::internal
