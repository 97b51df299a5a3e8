// Method auto: registration from any start.
//   1. The voxel clouds are aligned from the caller's start (coarse_alignment.h), then MLS-SICP
//      refines on the full-resolution target (skipped when the voxel alignment verifies and the
//      clouds' noise is under 1 d: registration/finish.h, RefinesBeforeFinish). A result that
//      verifies and covers enough of the source with the target (of what the target's sensor could
//      see, when known) goes to the finish (stage 4) and is returned, unless the finish contradicts
//      its verdict, or its weakest direction is fixed by so few samples that the rival search would
//      run (the global stage then runs too, and the start competes with its candidates).
//   2. Otherwise global candidates come from FPFH matches between the voxel clouds at the
//      feature scale (registration/global_candidates.h); each is aligned on the voxel clouds and
//      verified, and the start competes with them.
//   3. The best candidates are refined by MLS-SICP in turn until one verifies (the same skip).
//      A refinement that loses a verified voxel alignment gives way to it. When none verifies,
//      MLS-SICP alone from the caller's start (no voxel stage) is tried; when that does not
//      verify either, the start's result is returned, not verified.
//   4. A verified result, or one the data pull a little further (`pulled`), is polished over
//      every source point by the finish the clouds' noise chooses (registration/finish.h):
//      plane-to-plane on clean data, MLS on noisy data. The polished pose is kept when it
//      verifies. On a scan whose samples on one scan line the verification's settling corrects,
//      a pulled start settles before stage 2 and the settling replaces the finish
//      (SettleStart, SettlingIsLastStep).
//   5. A verified result that only a small share of the overlap fixes along one direction (a
//      corridor, whose doors and pillars may repeat) is searched for a rival: the voxel clouds
//      aligned again from the result moved along that direction. A rival, another pose that
//      explains as many samples, makes the result `ambiguous`, not verified
//      (SearchRivalThenFinish).
#include <algorithm>
#include <cmath>
#include <numeric>
#include <optional>

#include "coarse_alignment.h"
#include "method_runners.h"
#include "mlsreg/geometry/feature_cloud.h"
#include "mlsreg/registration/finish.h"
#include "mlsreg/registration/global_candidates.h"
#include "mlsreg/registration/verification.h"
#include "rival_search.h"

namespace mlsreg::internal {
namespace {

// RANSAC's inlier distance: Open3D's 1.5 voxels, or 3 noise sigmas when that is larger.
constexpr double kInlierDistancePerVoxel = 1.5;
constexpr double kInlierDistancePerNoise = 3.0;
// Candidates that get the full refinement when none before them verified.
constexpr int kRefinedCandidates = 3;
// A pulled pose explaining this much more of the source than a verified one replaces it
// (ClearlyBetterPulled); BetterScore calls poses within 1 % of each other the same answer.
constexpr double kAliasMargin = 0.05;
// The longest settling (in bands: the verification's mean inlier band) that PolishBySettling
// takes as the last step. 16-beam tuning scans from the prior settle 0.5-4 bands toward the
// truth; an open road's pose that settled 9 bands along the road verified 0.55 m off.
constexpr double kSettlePolishMaxBands = 5.0;
// Where at least this share of a verified pose's in-band samples lie on one scan line (and the
// settling corrected them), the settling is the last step instead of the finish
// (SettlingIsLastStep). Tuning scans from the prior: 16-beam streets 0.059-0.115, where the finish
// moved every settled pose (right, 0.003-0.04 m off) 0.9-5.5 bands and did not verify; 64-beam
// corridors and open roads at 1 cm 0.001-0.027, where the finish verified the right poses
// nearer the truth (0.021 -> 0.004 m) and refused two settled poses 0.41 and 1.25 m off.
constexpr double kSettledOverFinishShare = 0.04;

class AutoRegistration {
 public:
  explicit AutoRegistration(const RegistrationProblem& problem)
      : problem_(problem), target_(*problem.target), params_(problem.options->automatic) {
    full_ = *problem.options;
    full_.method = Method::kMlsSicp;
    // With a finish to come, the refinements project onto the target's patches only: the
    // finish, over every source point, decides the last digits.
    if (params_.finish) full_.mls.projection = MlsProjectionKind::kPatches;
    base_ = problem;
    if (!base_.source_tree) {
      own_source_tree_.emplace(problem.source->points, problem.threads);
      base_.source_tree = &*own_source_tree_;
    }
    // Every refinement and the finish analyse the source at the same radius: each point once.
    source_surface_.emplace(problem.source->points, *base_.source_tree, problem.source->viewpoint);
    base_.source_surface = &*source_surface_;
  }

  absl::StatusOr<RegistrationResult> Run() {
    // Stage 1: from the caller's start.
    Clock::time_point phase = Clock::now();
    source_voxels_ = BuildVoxelCloud(problem_.source->points, target_.voxel_cloud().voxel,
                                     problem_.source->viewpoint, problem_.threads);
    source_voxels_.sensor = problem_.source_sensor;
    RegistrationResult start =
        AlignCoarse(problem_.initial, Stage::kCoarse, 0, 0, problem_.options->max_iterations);
    start_capture_ = last_capture_;
    if (start.termination == Termination::kCancelled) return Finish(std::move(start));
    // Refined by MLS-SICP unless the voxel alignment may go straight to the finish. A pulled start
    // of a scan whose settled pose verifies over enough of the source is that pose at once
    // (SettleStart): the voxel alignment's before any refinement, else the refinement's.
    std::optional<VerificationScore> coarse_score;
    if (FinishesFromVoxels()) {
      coarse_score = Verify(start.transform);
      SettleStart(start, *coarse_score);
    }
    if (!coarse_score || !Acceptable(*coarse_score)) {
      absl::StatusOr<VerificationScore> score =
          RefineKeepingVerified(start, Stage::kStart, 0, coarse_score);
      if (!score.ok()) return score.status();
      if (start.termination == Termination::kCancelled) return Finish(std::move(start));
      coarse_score = *std::move(score);
      SettleStart(start, *coarse_score);
    }
    report_.candidates.push_back({CandidateOrigin::kStart, problem_.initial, start.transform, 0,
                                  start.iterations, *std::move(coarse_score), Seconds(phase)});
    report_.timings.start = Seconds(phase);
    best_score_ = report_.candidates[0].score;
    // A settled start needs no global stage: the finish polishes and judges it below as any
    // verified start, or where the settling is the last step (SettlingIsLastStep) the settling
    // has done so (docs/scenes.md, "The settled start").
    //
    // A verified start whose weakest direction few samples fix (SearchesForRival) may be an alias
    // farther along it than the rival search looks. Where the target's sensor is known, the
    // verification's seen-through test judges such a slide: the source's cars and poles stand
    // where the target's beams passed (two street scans 10 m apart, from the identity: the
    // start's refinement 10 m along the street has 11 % of its samples seen through). Elsewhere
    // the global stage runs, and the start competes with its candidates.
    const bool sensor_judges_slides = target_.sensor_view() != nullptr;
    if (Acceptable(best_score_) && (sensor_judges_slides || !SearchesForRival(best_score_))) {
      absl::StatusOr<RegistrationResult> polished = ApplyFinish(start);
      if (!polished.ok()) return polished.status();
      if (polished->termination == Termination::kCancelled) return Cancelled(start);
      // The finish moved the start's verified pose beyond its settling bound: the data put the
      // pose elsewhere, and the global stage runs as for a start that did not verify (a held-out
      // street pose slid 1.6 m that verified over 89 % of what the target's sensor could see;
      // the global stage found the right pose).
      if (!report_.finish.contradicted) {
        report_.early_exit = true;
        if (report_.finish.kept) report_.polished_by_settling = false;
        return SearchRivalThenFinish(*std::move(polished));
      }
      report_.candidates[0].score = best_score_;  // now pulled
      report_.finish = FinishReport{};
    }
    report_.polished_by_settling = false;

    // Stage 2: global candidates from feature matches, each aligned on the voxel clouds.
    phase = Clock::now();
    const StopCheck& should_stop = problem_.callbacks->should_stop;
    const FeatureCloud* target_features = target_.features(should_stop);
    if (!target_features) return Cancelled(std::move(start));
    const std::optional<FeatureCloud> source_features =
        BuildVoxelFeatureCloud(problem_.source->points, target_features->scale,
                               problem_.source->viewpoint, should_stop, problem_.threads);
    if (!source_features) return Cancelled(std::move(start));
    GlobalCandidateOptions global_options;
    global_options.max_candidates = params_.candidates;
    global_options.inlier_distance =
        std::max(kInlierDistancePerVoxel * target_features->scale.voxel,
                 kInlierDistancePerNoise * problem_.noise);
    global_options.seed = problem_.options->seed;
    const GlobalCandidates global =
        FindGlobalCandidates(*source_features, *target_features, global_options, should_stop);
    if (global.stopped) return Cancelled(std::move(start));
    report_.feature_matches = global.matches;
    report_.timings.global = Seconds(phase);
    ReportGlobalStage(global);

    phase = Clock::now();
    std::vector<RegistrationResult> aligned;
    // From a verified start, a candidate's alignment stops once it reaches the start's basin.
    const bool start_verified = report_.candidates[0].score.verified();
    for (std::size_t k = 0; k < global.candidates.size(); ++k) {
      const Clock::time_point t = Clock::now();
      const int index = static_cast<int>(k) + 1;
      const Matrix4& from = global.candidates[k].transform;
      RegistrationResult r =
          AlignCoarse(from, Stage::kCandidate, index, 0, params_.candidate_iterations,
                      start_verified ? &start.transform : nullptr);
      if (r.termination == Termination::kCancelled) return Cancelled(std::move(start));
      const bool in_start_basin = start_verified && InBasinOf(start.transform, r.transform);
      report_.candidates.push_back(
          {CandidateOrigin::kGlobal, from, r.transform, global.candidates[k].inliers, r.iterations,
           in_start_basin ? report_.candidates[0].score : Verify(r.transform), Seconds(t),
           in_start_basin});
      aligned.push_back(std::move(r));
      // A candidate that verifies over enough of the source ends the search, as the start would
      // have (Acceptable): the candidates after it, with fewer feature inliers, are not tried.
      if (!in_start_basin && Acceptable(report_.candidates.back().score)) break;
    }
    report_.timings.candidates = Seconds(phase);

    // Stage 3: the best candidates refined fully, best first, until one verifies.
    phase = Clock::now();
    std::vector<int> order(report_.candidates.size());
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
      return BetterScore(report_.candidates[a].score, report_.candidates[b].score);
    });
    std::optional<RegistrationResult> best;
    int refined = 0;
    for (int k : order) {
      if (k == 0) {  // the start: already refined
        if (!best) {
          report_.chosen = 0;
          best_score_ = report_.candidates[0].score;
          best = start;
        }
        continue;
      }
      // The start's answer again: verified, where a candidate that verifies ends the search.
      if (report_.candidates[k].in_start_basin) break;
      if (refined++ == kRefinedCandidates) break;
      RegistrationResult winner = aligned[k - 1];  // kept: it may yet replace an alias
      VerificationScore score = report_.candidates[k].score;
      if (!FinishesFromVoxels() || !score.verified()) {
        absl::StatusOr<VerificationScore> refined_score =
            RefineKeepingVerified(winner, Stage::kFinal, k, score);
        if (!refined_score.ok()) return refined_score.status();
        if (winner.termination == Termination::kCancelled) return Cancelled(std::move(winner));
        score = *std::move(refined_score);
      }
      if (!best || BetterScore(score, best_score_)) {
        report_.chosen = k;
        best_score_ = score;
        best = std::move(winner);
      }
      if (score.verified()) break;
    }
    // Still nothing verified: MLS-SICP itself from the caller's start, without the voxel stage,
    // competes last. The voxel alignment approximates the start's basin cheaply but can slide
    // along a few large planes (a machined part turned 30 degrees), and such parts lack the
    // features the global stage needs.
    if (!best_score_.verified()) {
      const Clock::time_point t = Clock::now();
      const int index = static_cast<int>(report_.candidates.size());
      absl::StatusOr<RegistrationResult> direct = Refine(problem_.initial, Stage::kFinal, index, 0);
      if (!direct.ok()) return direct.status();
      if (direct->termination == Termination::kCancelled) return Cancelled(std::move(*best));
      VerificationScore score = Verify(direct->transform);
      report_.candidates.push_back({CandidateOrigin::kDirect, problem_.initial, direct->transform,
                                    0, direct->iterations, score, Seconds(t)});
      if (score.verified()) {
        report_.chosen = index;
        best_score_ = std::move(score);
        best = *std::move(direct);
      }
    }
    // A verified pose that explains clearly less than a pulled one is an alias of it: the pulled
    // pose (the start's refinement, or a candidate's voxel alignment) goes to the finish instead,
    // and verifies only if it does after that.
    if (best_score_.verified()) {
      const int with_poses = 1 + static_cast<int>(aligned.size());  // the start and the global
      if (const std::optional<int> k = ClearlyBetterPulled(best_score_, with_poses)) {
        report_.chosen = *k;
        best_score_ = report_.candidates[*k].score;
        best = *k == 0 ? start : aligned[*k - 1];
      }
    }
    // Nothing verified: the caller's start is the best information left, so its refinement is
    // returned (not verified) rather than a pose from anywhere that merely explains more; unless
    // the best result is one small motion from a pose the data fix and the start's is not, or the
    // start's refinement has left the target altogether (UnverifiedPrefersTheStart).
    if (!best_score_.verified() && report_.chosen != 0 &&
        UnverifiedPrefersTheStart(report_.candidates[0].score, best_score_)) {
      report_.chosen = 0;
      best_score_ = report_.candidates[0].score;
      best = std::move(start);
    }
    report_.timings.final = Seconds(phase);
    return Polish(std::move(*best));
  }

 private:
  // The voxel clouds aligned from `start`, the capture range starting at what the start leaves
  // between them (never fails; may be cancelled).
  // With `basin_of`, the alignment ends once it reaches that pose's basin (InBasinOf).
  RegistrationResult AlignCoarse(const Matrix4& start, Stage stage, int candidate,
                                 int iteration_offset, int max_iterations,
                                 const Matrix4* basin_of = nullptr) {
    const RegistrationCallbacks callbacks = StampedCallbacks(*problem_.callbacks, stage, candidate);
    RegistrationProblem problem = base_;
    problem.initial = start;
    problem.callbacks = &callbacks;
    problem.iteration_offset = iteration_offset;
    CoarseSchedule schedule =
        ScheduleFrom(target_, source_voxels_, start, max_iterations, problem_.threads);
    if (basin_of) {
      schedule.reached = [this, basin_of](const RigidTransform& pose) {
        return InBasinOf(*basin_of, pose.matrix());
      };
    }
    last_capture_ = {schedule.start_capture, schedule.final_capture};
    RegistrationResult result =
        AlignVoxelClouds(problem, target_.voxel_cloud(), source_voxels_, schedule);
    Stamp(result, stage, candidate);
    return result;
  }

  // Whether `pose` lies in the basin of the verified pose `found`: within the coarse
  // alignment's final capture range of it (the RMS displacement of the source's voxel samples),
  // from where an alignment ends at `found` and its verdict repeats found's. Tuning streets from
  // the prior: 71 of 96 starts verified with less than accept_fraction of the source covered; the
  // global stage that followed brought most of its candidates back to the start's pose (1.3-41 m,
  // most under 10 m, away as RANSAC left them, 0.01-0.04 m after alignment), chose the start's pose
  // or one within centimetres of it every time, and took 0.85 s per registration against 0.29 s
  // without it. A candidate in another basin (a roundish object turned about its axis) is aligned
  // and verified as before.
  bool InBasinOf(const Matrix4& found, const Matrix4& pose) const {
    return RmsDistanceBetween(source_voxels_.points, found, pose) <=
           kFinalCaptureVoxels * target_.voxel_cloud().voxel;
  }

  // Among the first `count` candidates (the start and the voxel alignments), the one whose pose
  // is `pulled` yet explains at least kAliasMargin more of the source than the verified
  // `verified`, the most such; none when there is none. A pulled pose passed every test before the
  // pull, and the right pose explains the most: a verified pose that explains clearly less is an
  // alias (a corridor's repeated structure: a pose slid 0.77 m verified with 13 % fewer inliers
  // than the start's refinement, 1 cm from the truth and pulled).
  std::optional<int> ClearlyBetterPulled(const VerificationScore& verified, int count) const {
    std::optional<int> found;
    for (int k = 0; k < count; ++k) {
      const VerificationScore& s = report_.candidates[k].score;
      if (s.verdict != Verdict::kPulled ||
          s.inliers < (1.0 + kAliasMargin) * static_cast<double>(verified.inliers)) {
        continue;
      }
      if (!found || s.inliers > report_.candidates[*found].score.inliers) found = k;
    }
    return found;
  }

  // When nothing verified, whether the start's refinement (score `start`) is returned rather
  // than the best other result (`best`, the most inliers). Not when `best` is `pulled` and the
  // start's is not: a pulled pose passed every test before the pull (overlap, agreement, noise-like
  // residuals), one small rigid motion from a pose the data fix, and the finish polishes it (an
  // open road from an odometry prior: a global candidate 0.2 m from the truth, pulled, against a
  // start refinement that slid off the road). Nor when the start's refinement covers too little
  // of the target while `best` covers enough: it no longer carries the caller's information.
  static bool UnverifiedPrefersTheStart(const VerificationScore& start,
                                        const VerificationScore& best) {
    if (best.verdict == Verdict::kPulled && start.verdict != Verdict::kPulled) return false;
    return !(start.verdict == Verdict::kTooLittleOverlap &&
             best.verdict != Verdict::kTooLittleOverlap);
  }

  // A voxel alignment that verifies goes straight to the finish (kRefineBeforeMlsFinishD).
  bool FinishesFromVoxels() const {
    return params_.finish && !RefinesBeforeFinish(problem_.noise_d);
  }

  // `aligned` (a voxel alignment) refined by MLS-SICP, and the refined pose's verification. A
  // refinement that does not verify where the voxel alignment did (`voxel_score`, when known), or
  // that explains less than it (BetterScore: an open road, where Sparse ICP's steps from a pose
  // 0.2 m off slid off the target), gives way to it: the finish polishes that one instead.
  absl::StatusOr<VerificationScore> RefineKeepingVerified(
      RegistrationResult& aligned, Stage stage, int candidate,
      const std::optional<VerificationScore>& voxel_score) {
    const Matrix4 voxel_pose = aligned.transform;
    absl::StatusOr<RegistrationResult> full =
        Refine(voxel_pose, stage, candidate, aligned.iterations);
    if (!full.ok()) return full.status();
    AppendPhase(aligned, *std::move(full));
    if (aligned.termination == Termination::kCancelled) return VerificationScore{};
    VerificationScore score = Verify(aligned.transform);
    if (score.verified() || !params_.finish) return score;
    const VerificationScore voxel = voxel_score ? *voxel_score : Verify(voxel_pose);
    if (!voxel.verified() && !BetterScore(voxel, score)) return score;
    aligned.transform = voxel_pose;
    return voxel;
  }

  // MLS-SICP with every default from `start`.
  absl::StatusOr<RegistrationResult> Refine(const Matrix4& start, Stage stage, int candidate,
                                            int iteration_offset) {
    const RegistrationCallbacks callbacks = StampedCallbacks(*problem_.callbacks, stage, candidate);
    RegistrationProblem problem = base_;
    problem.initial = start;
    problem.options = &full_;
    problem.callbacks = &callbacks;
    problem.iteration_offset = iteration_offset;
    absl::StatusOr<RegistrationResult> result = RunSparseIcp(problem);
    if (result.ok()) Stamp(*result, stage, candidate);
    return result;
  }

  // Stage 4: a verified (or pulled) result polished by the finish the noise chooses, over every
  // source point (up to kFinishMaxSamples); its pose is kept when it ran on enough pairs and
  // verifies in turn, so the verdict is always of the pose returned.
  absl::StatusOr<RegistrationResult> Polish(RegistrationResult result) {
    absl::StatusOr<RegistrationResult> polished = ApplyFinish(std::move(result));
    if (!polished.ok()) return polished.status();
    if (polished->termination == Termination::kCancelled) return Cancelled(*std::move(polished));
    return SearchRivalThenFinish(*std::move(polished));
  }

  // The finish of Polish, without the rival search: `result` with the finish's phase appended
  // when its pose is kept (best_score_ and report_.finish updated), else `result` as it was
  // (best_score_ `pulled` when the finish contradicted it); cancelled when the finish was. A
  // verified result whose settling is the last step (SettlingIsLastStep) takes its settled pose
  // instead when that verifies, and no finish runs.
  absl::StatusOr<RegistrationResult> ApplyFinish(RegistrationResult result) {
    if (!params_.finish || !FinishPolishes(best_score_.verdict)) return result;
    if (best_score_.verified() && SettlingIsLastStep(best_score_) && SettleVerified(result)) {
      return result;
    }
    const Clock::time_point phase = Clock::now();
    FinishReport& finish = report_.finish;
    finish.noise_d = problem_.noise_d;
    finish.crossover_d = kMlsFitFloorD;
    finish.kind = ChooseFinish(problem_.noise_d);
    RegistrationOptions options = full_;
    options.num_samples = kFinishMaxSamples;
    options.mls.projection = MlsProjectionKind::kPatches;
    // From a verified pose, a source point with no target sample within r lies outside the
    // overlap: seeding it from its nearest sample would only pull the pose.
    options.mls.far_queries = FarQueryPolicy::kDrop;
    const RegistrationCallbacks callbacks =
        StampedCallbacks(*problem_.callbacks, Stage::kFinish, report_.chosen);
    RegistrationProblem problem = base_;
    problem.initial = result.transform;
    problem.options = &options;
    problem.callbacks = &callbacks;
    problem.iteration_offset = result.iterations;
    problem.drop_first_rejections = true;
    absl::StatusOr<RegistrationResult> polished =
        finish.kind == FinishKind::kMls ? RunSparseIcp(problem) : RunPlaneToPlaneFinish(problem);
    if (!polished.ok()) return polished.status();
    if (polished->termination == Termination::kCancelled) {
      result.termination = Termination::kCancelled;
      return result;
    }
    Stamp(*polished, Stage::kFinish, report_.chosen);
    finish.samples = polished->num_samples;
    finish.iterations = polished->iterations;
    finish.moved = RmsDistanceBetween(source_voxels_.points, result.transform, polished->transform);
    if (polished->termination != Termination::kTooFewCorrespondences) {
      VerificationScore score = Verify(polished->transform);
      finish.kept = score.verified();
      if (finish.kept) {
        best_score_ = std::move(score);
        AppendPhase(result, *std::move(polished));
      } else {
        // The finish is the settling over every source point: a verified pose it moves beyond
        // the verdict's settling bound, to a pose that does not verify, is not where the data
        // put it. Tuning corridors from the prior: 5 of the 14 poses 0.3-1.3 m off along the
        // corridor that verified were such (the finish moved them 0.8-23 bands), and 4 right
        // ones (0.6-7 bands); on the tuning streets, KITTI and the objects every finish of a
        // verified pose verified in turn.
        finish.contradicted =
            PulledBySettling(best_score_, finish.moved, target_.scales().median_spacing);
      }
    }
    finish.seconds = Seconds(phase);
    return result;
  }

  // Stage 5: a verified result that few samples fix along one direction is checked for a rival
  // (rival_search.h); one makes it `ambiguous`.
  absl::StatusOr<RegistrationResult> SearchRivalThenFinish(RegistrationResult result) {
    if (!SearchesForRival(best_score_)) return Finish(std::move(result));
    if (!SearchRivalOf(result.transform)) return Cancelled(std::move(result));
    return Finish(std::move(result));
  }

  // The rival search around the verified `pose` (best_score_ its score): its probes join the
  // candidates, and a rival makes the verdict `ambiguous`. It reaches farther for a pose the
  // global stage found (RivalReach). False when cancelled.
  bool SearchRivalOf(const Matrix4& pose) {
    const int first = static_cast<int>(report_.candidates.size());
    const bool found_globally =
        report_.chosen < first &&
        report_.candidates[report_.chosen].origin == CandidateOrigin::kGlobal;
    RivalSearch search = SearchRival(
        pose, best_score_, source_voxels_, target_.voxel_cloud().voxel,
        [&](const Matrix4& from, int k) {
          return AlignCoarse(from, Stage::kRival, first + k, 0, params_.candidate_iterations);
        },
        [&](const Matrix4& probe, const VerificationOptions& options) {
          return Verify(probe, options);
        },
        found_globally ? RivalReach::kFar : RivalReach::kNear);
    for (AutoCandidate& probe : search.probes) report_.candidates.push_back(std::move(probe));
    report_.timings.rivals += search.seconds;
    if (search.cancelled) return false;
    if (search.rival) {
      report_.rival = first + *search.rival;
      best_score_.verdict = Verdict::kAmbiguous;
    }
    return true;
  }

  // The verification of the pose where the settling stopped a `pulled` result of a scan (a
  // target whose sampling shows its sensor), when that pose verifies; none otherwise. The
  // settling is point-to-plane on the MLS patches over the verification's samples (one per working
  // voxel), with the normals of samples on one scan line corrected; on 16-beam scans it lands
  // nearer the truth than the finish, which no change to the finish tried reached
  // (docs/scenes.md, "The settling as the last step"). Only a small step: at most
  // kSettlePolishMaxBands bands, as a pulled pose is one small rigid motion short of the data's
  // optimum; a longer settling (an open road, nothing fixing the slide along it) is left pulled.
  std::optional<VerificationScore> SettledScore(const VerificationScore& pulled) const {
    if (!target_.scan_sensor() || pulled.verdict != Verdict::kPulled || !pulled.settled_pose ||
        pulled.settle_displacement > kSettlePolishMaxBands * pulled.inlier_distance) {
      return std::nullopt;
    }
    VerificationScore score = Verify(*pulled.settled_pose);
    if (!score.verified()) return std::nullopt;
    return score;
  }

  // A pulled start (`score` its verification) moved to its settled pose when that pose verifies
  // over enough of the source (Acceptable) and the target's sensor is known, as it judges a slide
  // along the weakest direction (see Run). 16-beam streets from the prior: most starts are
  // pulled, their settled poses right, and the global stage that followed took 70 % of the time.
  void SettleStart(RegistrationResult& start, VerificationScore& score) {
    if (target_.sensor_view() == nullptr || Acceptable(score)) return;
    std::optional<VerificationScore> settled = SettledScore(score);
    if (!settled || !Acceptable(*settled)) return;
    start.transform = *score.settled_pose;
    score = *std::move(settled);
    report_.polished_by_settling = true;
  }

  // Whether the settling of `score` is the last step rather than the finish: it corrected the
  // samples on one scan line (its settled pose is known), and they are at least
  // kSettledOverFinishShare of its in-band samples. The finish does not correct them, and on
  // 16-beam streets it lands farther from the truth (docs/scenes.md, "The settled start").
  static bool SettlingIsLastStep(const VerificationScore& score) {
    return score.settled_pose && score.one_scan_line_share >= kSettledOverFinishShare;
  }

  // A verified `result` (best_score_ its score) moved to its settled pose when that verifies in
  // turn (or already there: a settled start); false when the settled pose does not verify.
  bool SettleVerified(RegistrationResult& result) {
    if (report_.polished_by_settling) return true;
    VerificationScore score = Verify(*best_score_.settled_pose);
    if (!score.verified()) return false;
    result.transform = *best_score_.settled_pose;
    best_score_ = std::move(score);
    report_.polished_by_settling = true;
    return true;
  }

  // A `pulled` result replaced by its settled pose when that verifies (SettledScore); the rival
  // search then runs as for any verified result, and a rival makes it `ambiguous`.
  void PolishBySettling(RegistrationResult& result) {
    if (report_.candidates.empty() || report_.polished_by_settling) return;
    std::optional<VerificationScore> score = SettledScore(best_score_);
    if (!score) return;
    const VerificationScore pulled = best_score_;
    const Matrix4 settled = *pulled.settled_pose;
    best_score_ = *std::move(score);
    if (SearchesForRival(best_score_) && !SearchRivalOf(settled)) {
      best_score_ = pulled;  // cancelled: the result stands as it was
      return;
    }
    result.transform = settled;
    report_.polished_by_settling = true;
  }

  // Verified, with enough of the source over the target's data to need no global stage.
  bool Acceptable(const VerificationScore& score) const {
    return score.verified() && score.visible_covered_fraction() >= params_.accept_fraction;
  }

  VerificationScore Verify(const Matrix4& transform,
                           const VerificationOptions& options = {}) const {
    return VerifyAlignment(target_, source_voxels_, transform, problem_.noise_levels, options,
                           problem_.threads, &verification_caches_);
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

  absl::StatusOr<RegistrationResult> Finish(RegistrationResult result) {
    if (result.termination != Termination::kCancelled) PolishBySettling(result);
    if (!report_.candidates.empty() && result.termination != Termination::kCancelled) {
      report_.verification = best_score_;
      report_.verified = report_.verification.verified();
    }
    result.auto_report = std::move(report_);
    result.scales.capture_start = start_capture_.first;
    result.scales.capture_end = start_capture_.second;
    return result;
  }

  const RegistrationProblem& problem_;
  const Target& target_;
  const AutoParams& params_;
  RegistrationOptions full_;
  RegistrationProblem base_;
  std::optional<KdTree> own_source_tree_;
  std::optional<SurfaceCache> source_surface_;
  VoxelCloud source_voxels_;
  // The samples' neighbours, kept from one verification to the next (Verify is sequential).
  mutable VerificationCaches verification_caches_;
  VerificationScore best_score_;  // of the result so far
  // The capture range (first, last) of the last coarse alignment, and of the start's.
  std::pair<double, double> last_capture_, start_capture_;
  AutoReport report_;
};

}  // namespace

absl::StatusOr<RegistrationResult> RunAuto(const RegistrationProblem& problem) {
  return AutoRegistration(problem).Run();
}

}  // namespace mlsreg::internal
