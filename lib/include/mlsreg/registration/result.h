// What a registration reports: one IterationReport per ICP iteration (streamed through the
// callbacks), and the RegistrationResult at the end.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mlsreg/core/enum_names.h"
#include "mlsreg/core/transform.h"
#include "mlsreg/correspondences/correspondence_filter.h"
#include "mlsreg/registration/verification.h"

namespace mlsreg {

// The stage of method auto an iteration belongs to (kSingle for every other method).
enum class Stage {
  kSingle,     // a method with one stage
  kStart,      // auto: MLS-SICP from the caller's start
  kGlobal,     // auto: global candidates from feature matches (one report, iteration 0)
  kCandidate,  // auto: the cheap refinement of a global candidate (IterationReport::candidate)
  kFinal,      // auto: the full refinement of the best candidate
  kCoarse,     // auto: voxel clouds aligned at the working resolution (registration/scales.h)
  kFinish,     // auto: the chosen pose polished over every source point (registration/finish.h)
  kRival,  // auto: the voxel clouds aligned again from the verified pose moved (AutoReport::rival)
};
// "single", "start", "global", "candidate", "final", "coarse", "finish", "rival"
std::string_view StageName(Stage stage);
const EnumNames& StageNames();  // wire enum "Stage"

// Streamed once per ICP iteration.
struct IterationReport {
  int iteration = 0;                        // 1-based
  Matrix4 transform = Matrix4::Identity();  // after this iteration's update
  double rmse = 0.0;    // RMSE of this iteration's accepted correspondences (absolute units)
  double rmse_d = 0.0;  // the same in units of d
  CorrespondenceCounts counts;
  int admm_iterations = 0;
  double elapsed_seconds = 0.0;  // since Register was called
  Stage stage = Stage::kSingle;
  int candidate = -1;  // auto: the candidate (index into AutoReport::candidates), else -1
};

enum class Termination {
  kConverged,              // samples stopped moving, alternate between two poses, or reached
                           // a pose the run is known to converge to (auto's global candidates)
  kMaxIterations,          // max_iterations reached
  kCancelled,              // should_stop returned true
  kTooFewCorrespondences,  // fewer than min_correspondences survived the filters
};
std::string_view TerminationName(Termination termination);  // "converged", ...
const EnumNames& TerminationNames();                        // wire enum "Termination"

// Wall time of the phases of paper Figure 6.
struct PhaseTimings {
  double preprocessing = 0.0;  // source analysis (the target's is cached in Target)
  double subsampling = 0.0;
  double matching = 0.0;      // correspondence search + filtering
  double optimisation = 0.0;  // Sparse ICP ADMM
  double total = 0.0;
};

// Method auto: every pose it considered, how each verified, and which one won.
enum class CandidateOrigin {
  kStart,   // the caller's initial pose
  kGlobal,  // a pose from global feature matching
  // The caller's initial pose refined by MLS-SICP alone, without the voxel stage: tried last,
  // when nothing else verified.
  kDirect,
  // The verified result moved along its weakest direction and aligned again on the voxel clouds:
  // a search for another pose that explains the source as well (AutoReport::rival).
  kRival,
};
// "start", "global", "direct", "rival"
std::string_view CandidateOriginName(CandidateOrigin origin);
const EnumNames& CandidateOriginNames();  // wire enum "CandidateOrigin"

struct AutoCandidate {
  CandidateOrigin origin = CandidateOrigin::kStart;
  Matrix4 start = Matrix4::Identity();    // the pose refinement started from
  Matrix4 refined = Matrix4::Identity();  // after its refinement
  int feature_inliers = 0;                // kGlobal: feature matches the pose explains
  int iterations = 0;                     // of its refinement
  VerificationScore score;                // of `refined`
  double seconds = 0.0;                   // its refinement and verification
  // kGlobal: its alignment reached the verified start's pose (within the coarse alignment's
  // final capture range of it), where it would have converged too: it stopped there, was not
  // verified again, and `score` is the start's. kRival: it came back to the result (within
  // 1.5 verification bands), where it cannot be a rival: not verified, `score` is the result's.
  bool in_start_basin = false;
};

struct AutoStageTimings {
  double start = 0.0;       // MLS-SICP from the start, and its verification
  double global = 0.0;      // source features, matching, RANSAC
  double candidates = 0.0;  // cheap refinements and their verification
  double final = 0.0;       // the full refinement of the winner
  double rivals = 0.0;      // the search for a rival of the verified result
};

// Method auto's finish (registration/finish.h): how the chosen pose was polished.
enum class FinishKind {
  kNone,          // none ran: the pose did not verify, or the finish is switched off
  kPlaneToPlane,  // G-ICP's plane-to-plane step on the raw points: clean data
  kMls,           // MLS-SICP over every source point: noisy data
};
std::string_view FinishKindName(FinishKind kind);  // "none", "plane-to-plane", "mls"
const EnumNames& FinishKindNames();                // wire enum "FinishKind"

struct FinishReport {
  FinishKind kind = FinishKind::kNone;
  double noise_d = 0.0;      // the clouds' noise (the larger, units of d) that chose it
  double crossover_d = 0.0;  // plane-to-plane below this noise, MLS from it on
  int samples = 0;           // source points it used
  int iterations = 0;
  // Its pose replaced the refinement's: it ran on enough pairs and verified in turn (the result's
  // verification is then the finished pose's). False: the refinement's pose (verified, or
  // pulled and still not verified) is kept with its verdict.
  bool kept = false;
  double moved = 0.0;  // RMS displacement of the verification samples from the refined pose
  // Not kept, and it moved a verified pose beyond the verdict's settling bound
  // (PulledBySettling): the refined pose is returned `pulled`, not verified.
  bool contradicted = false;

  double seconds = 0.0;
};

struct AutoReport {
  std::vector<AutoCandidate> candidates;  // [0] is the start
  int chosen = 0;                         // index of the winner
  // The result's verification says it is right (VerificationScore::verified). When false the
  // transform is the best found but must not be trusted: no candidate fits.
  bool verified = false;
  VerificationScore verification;  // of the result
  // The start verified well enough (its weakest direction well fixed, or the target's sensor known
  // to judge a slide along it): no global stage ran.
  bool early_exit = false;
  int feature_matches = 0;  // matches the global stage drew from
  AutoStageTimings timings;
  FinishReport finish;
  // The candidate (origin kRival) at another pose that explains as many of the source's samples
  // as the verified result: the result is then `ambiguous`, not verified. None when no rival was
  // found, or none was searched for (the result did not verify, or every direction of motion is
  // fixed by a large share of the overlap).
  std::optional<int> rival;
  // The transform is where the verification's settling took the result, which verified there:
  // a `pulled` result of a scan, or a verified one where the settling is the last step instead of
  // the finish (samples on one scan line; docs/scenes.md, "The settled start"). The trace ends at
  // the pose before the settling.
  bool polished_by_settling = false;
};

// The lengths a registration worked at, all chosen from the data (absolute units, those of the
// clouds): what the user would otherwise have had to pick.
// A length the caller gave in the clouds' units ("--max-distance 1m"), and what it is in d.
struct UserLength {
  std::string parameter;  // the parameter table's name ("filter.max_distance_d")
  double value = 0.0;     // in the clouds' units
  double value_d = 0.0;   // in units of the target's d
};

struct ScaleReport {
  double mean_spacing = 0.0;    // the target's d (paper Eq. 11): the unit of every *_d field
  double median_spacing = 0.0;  // the target's median nearest-neighbour spacing
  double spacing_p90 = 0.0;     // and its 90th percentile (the sparse regions)
  double extent = 0.0;          // the target's robust size
  double working_voxel = 0.0;   // coarse alignment, global features and verification samples
  // Method auto: the capture range of the coarse alignment from the start, first and last.
  double capture_start = 0.0;
  double capture_end = 0.0;
  double mls_radius = 0.0;                    // methods with MLS correspondences
  double verification_band = 0.0;             // the verification's mean inlier band
  std::vector<UserLength> user_lengths = {};  // every length given in the clouds' units, by name
  // The target's sensor, where its sampling shows one (geometry/sensor_view.h): the verification
  // then counts the source samples that sensor could not have seen as hidden, not as uncovered.
  std::optional<Vec3> sensor = {};
};

struct RegistrationResult {
  Matrix4 transform = Matrix4::Identity();  // maps source points into the target frame
  bool converged = false;
  Termination termination = Termination::kMaxIterations;
  int iterations = 0;
  std::vector<IterationReport> trace;
  PhaseTimings timings;
  double sampling_distance = 0.0;  // the target's d, the unit of every *_d field
  int num_samples = 0;
  // Methods that read the MLS parameters: the support radius used (units of d) and whether it
  // was chosen automatically. The noise estimates of both clouds (units of d; 0 when not
  // estimated: an explicit radius without verification needs none).
  double mls_radius_d = 0.0;
  bool mls_radius_auto = false;
  double target_noise_d = 0.0;
  double source_noise_d = 0.0;
  std::optional<AutoReport> auto_report;  // method auto only
  // Whether the result can be trusted (RegistrationOptions::verify; any method). Unset when not
  // asked for or cancelled.
  std::optional<VerificationScore> verification;
  // Another pose that explains the source as well as the verified result (the rival search along
  // its weakest direction, any method): the verdict is then `ambiguous`. Method auto lists it
  // among its candidates too (AutoReport::rival).
  std::optional<AutoCandidate> rival;
  ScaleReport scales;
};

struct RegistrationCallbacks {
  std::function<void(const IterationReport&)> on_iteration;  // may be empty
  std::function<bool()> should_stop;  // polled once per iteration; true cancels (may be empty)
};

}  // namespace mlsreg
