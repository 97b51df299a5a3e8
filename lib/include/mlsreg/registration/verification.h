// Verification: whether a pose lays the source on the target, the verdict every registration
// reports and the score that picks among candidate poses.
//
// The source is sampled on its voxel cloud at the target's working voxel (samples follow the
// surface, not a LiDAR's rings). Each sample, moved by the pose, is
//   - covered when the target has data near it (a voxel of the target within a few working
//     voxels): only covered samples can confirm or contradict the pose, the rest lie outside the
//     overlap;
//   - an inlier when it also lies within the band of the target's surface: its MLS surface
//     (the target's MLS patches: de-noised, unbiased on curved surfaces) where the patches reach,
//     else the plane through its 12 nearest samples. The band is 3 sigma of the residual expected
//     where the sample lands: the target's measured noise, or the spread of its samples about
//     their voxel's plane there when larger (a LiDAR's noise grows with range), combined with the
//     source's; at least one median spacing of the target. It is generous on purpose: it tells
//     the overlap from chance, the pull below tells how precisely the pose sits.
// A right pose explains most of the overlap, its inliers' residuals concentrate inside the band
// and are noise (neighbouring samples do not share them: a surface of another shape, another
// object moved onto the target, leaves residuals that neighbours share), and the agreeing
// samples fix every direction of motion: along each, the pose's standard error
// (their residual RMS over the square root of their point-to-plane information there) is at
// most one noise sigma. This catches a pose slid along a road or a corridor: the ground and the
// facades still agree, but the few samples that fix the slide (poles, building ends) do not; it
// counts all of them together, so a long street whose few cross structures fix the pose well
// verifies, and one moving car among them does not decide. A direction that not even the
// covered samples fix (a bare road, a plane) cannot be verified at all.
// Last, the pull: a right pose is where the data put it. One point-to-plane step from it would
// explain only noise (about 6 / inliers of the residuals' sum of squares), and settling (a few
// such steps on the target's surface) moves the inliers by its registration precision, a
// fraction of the noise. A pose turned or slid off the truth by less than the band is pulled
// back toward it: one step explains much of its residuals, and it settles far away.
#pragma once

#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "mlsreg/core/enum_names.h"
#include "mlsreg/core/transform.h"
#include "mlsreg/geometry/mls_patches.h"
#include "mlsreg/geometry/neighbor_cache.h"
#include "mlsreg/geometry/target.h"

namespace mlsreg {

struct VerificationOptions {
  double band_per_noise = 3.0;          // the band is this many combined noise sigmas...
  double min_band_spacings = 1.0;       // ...and at least this many median spacings of the target
  double coverage_voxels = 1.0;         // covered: a target voxel within this many working voxels
  double min_inlier_fraction = 0.5;     // of the covered samples
  double min_explained_fraction = 0.1;  // of all samples
  double min_covered_samples = 30;
  // A uniform spread of residuals over the band has an RMS of 0.58 band; a real fit's (Gaussian,
  // even with the noise underestimated twofold) at most about 0.45.
  double max_rms_per_band = 0.5;
  // The residuals' part that neighbouring inliers (within two working voxels) share, after the
  // pull's rigid step, at most this many noise sigmas of the band. Noise shares nothing; at a
  // right pose the shared part is the MLS surface's own bias: 0.15-0.57 sigma at sigma <= 0.8 d,
  // up to 0.84 at 4 d (the radius grows with the noise), at most 0.69 on real scans (tuning
  // sets, verification study). Registrations of two different objects share 0.84-1.34.
  double max_coherent_sigmas = 0.9;
  // Every direction of motion must be fixed by the agreeing samples to a standard error of at
  // most this many noise sigmas of the band (band / band_per_noise): the band then holds the
  // pose to about three standard errors. The error is the inliers' residual RMS over the square
  // root of their point-to-plane information along the direction.
  double max_direction_error_sigmas = 1.0;
  // ...and its information must be real: the product of the source's and the target's normals
  // (whose noise is independent) summed over the agreeing samples must exceed this many times
  // its own scatter (a z-score: a bare road's noise-tilted normals give about 0 +- 1).
  double min_direction_z = 3.0;
  // ...counting only samples whose own normal and the target's agree as noise lets them: within
  // feature_angle_per_median times the agreeing samples' median angle between the two (noise
  // alone exceeds three medians about once in 500 samples) and never less than
  // min_feature_angle_deg. A sample beyond that sits on a sharp edge, where each cloud's normal
  // comes from a different face: its product of normals is arbitrary and would drown the
  // information of a clean CAD part's faces.
  double feature_angle_per_median = 3.0;
  double min_feature_angle_deg = 30.0;
  // The samples reported as constraining the weakest direction: those it moves by at least this
  // share of the top percentile's sensitivity (rotations in units of the samples' RMS radius).
  double direction_sensitivity = 0.5;
  // The pose is pulled when one rigid motion would remove more than this share of the inliers'
  // squared residuals (a right pose's residuals are noise: about 6 / inliers of them).
  double max_pull_fraction = 0.1;
  // ...or when, settling where the data put it, it moves the inliers by more than this many
  // noise sigmas (the band's): a right pose moves by its registration precision, a fraction of
  // the noise. A pose that settles within one median spacing (min_band_spacings) is never
  // pulled: on clean data every imprecise pose is pulled significantly, but not by much.
  double max_settle_sigmas = 1.0;
  // The settling ends once a step moves the samples by less than this many noise sigmas. Steps
  // shrink 3-5x each near a pose (a tuning street: 0.88, 0.21, 0.04 sigma), so what is left then
  // is about 1 % of a sigma; at 0.01 every settling ran all six steps. A rival probe's settling
  // is subtracted from its distance to the result (rival_search.h) and runs to 0.01.
  double settle_tolerance_sigmas = 0.05;
  // Where the target's sensor is known (SensorView), at most this share of the samples it could
  // judge may lie where it saw through them: more than the coverage distance (one working voxel
  // plus the band) in front of every return around their direction. At a right pose only what
  // moved between the scans lies there (tuning streets and KITTI: 0-0.7 %); a street pose slid
  // 1 m puts 2.1-9.1 % of the samples there (47 of 49 pairs over 3 %), 3 m 4.3-19 % (cars,
  // poles and cross walls in the street; docs/verification.md, "Seen through").
  double max_seen_through_fraction = 0.03;
  // Where both scans' sensors are known, at most this share of the inliers judged may have the
  // source's sensor behind their surface (on the other side of it from the target's sensor: it
  // would have seen the surface from behind). Judged are the inliers whose plane both sensors
  // lie off by more than the band and by min_side_view_angle_deg as seen from the inlier: a
  // normal fitted over one LiDAR ring far from the sensor tilts about the ring, and a grazing
  // view would change side with it. At a right pose only thin surfaces seen from both sides lie
  // there (KITTI at the truth: 0-0.5 %; the tuning streets, corridors and open road: 0-1.4 %);
  // a street scan laid upside down with its road on the target's road puts 84 % there (its
  // facades hidden below the road, nothing seen through). The share speaks from
  // min_sides_judged inliers judged: on an open road few surfaces face both sensors, and a pole
  // thinner than the band, seen from both sides, is then a large share of a dozen (5 of 13 on
  // a right pose).
  double max_seen_from_behind_fraction = 0.10;
  double min_side_view_angle_deg = 15.0;
  int min_sides_judged = 30;
};

enum class Verdict {
  kVerified,
  kTooLittleOverlap,  // too few covered samples
  kLowAgreement,      // too small a share of the overlap lies on the surface
  kDiffuseResiduals,  // the inliers' residuals spread over the band (chance overlap)
  // The agreeing samples do not fix one direction of motion within a noise sigma, though the
  // covered ones would: the samples that would fix it disagree (a pose slid along a road).
  kDirectionDisagrees,
  kUnconstrained,  // not even the covered samples fix one direction of motion
  kPulled,         // one small rigid motion would remove much of the residuals
  // Neighbouring samples share their residuals: the surfaces differ in shape (another object).
  kCoherentResiduals,
  // The pose passes every test above, but another pose along its weakest direction explains as
  // many samples (method auto's rival search: a corridor whose doors and pillars repeat).
  kAmbiguous,
  // The target's sensor saw through too many samples: its beams passed where the pose puts them
  // (a street pose slid along the road lays parked cars and poles on the open road).
  kSeenThrough,
  // The source's sensor would have seen too many of the inliers' surfaces from behind: the pose
  // puts it on the other side of them from the target's sensor (a scan laid upside down).
  kSeenFromBehind,
};
std::string_view VerdictName(Verdict verdict);  // "verified", "too_little_overlap", ...
const EnumNames& VerdictNames();                // wire enum "Verdict"

struct VerificationScore {
  int samples = 0;  // source samples tried
  int covered = 0;  // samples with target data near them
  // Samples not covered that the target's sensor could not have seen (behind what it saw, or
  // where it saw nothing: SensorView); 0 when the target shows no sensor.
  int hidden = 0;
  // Samples the target's sensor saw through (SensorView::SeesThrough, the coverage distance in
  // front of every return around them); 0 when the target shows no sensor.
  int seen_through = 0;
  // Where both scans' sensors are known: the inliers whose surface both sensors lie clearly off
  // (more than the band and min_side_view_angle_deg from its plane), and of those, the ones the
  // pose puts the source's sensor behind (on the other side of the surface from the target's).
  int sides_judged = 0;
  int seen_from_behind = 0;
  int inliers = 0;                  // covered samples on the surface
  double inlier_fraction = 0.0;     // inliers / covered: the share of the overlap explained
  double explained_fraction = 0.0;  // inliers / samples
  double rmse_d = 0.0;              // RMSE of the inliers' distances, units of d
  double inlier_distance_d = 0.0;   // the band (the inliers' mean where it varies), units of d
  double inlier_distance = 0.0;     // the same, absolute
  double noise = 0.0;               // the clouds' combined noise sigma, absolute
  // The inliers' residuals against the noise expected where each lands: their RMS in units of
  // that sigma over what a right pose gives (0.973: a unit Gaussian cut at the 3-sigma band).
  // About 1 for a right pose; a wrong pose's residuals are wider than the noise.
  double residual_scale = 0.0;
  // The pull: the share of the inliers' squared residuals that one rigid motion would remove, and
  // that motion (the point-to-plane step from the pose).
  double pull_fraction = 0.0;
  double pull_rotation_deg = 0.0;
  double pull_translation = 0.0;
  double pull_displacement = 0.0;  // the RMS distance that motion moves the inliers by
  // The RMS distance the inliers travel when the pose settles where the data put it (a few
  // point-to-plane steps on the target's surface).
  double settle_displacement = 0.0;
  // Where that settling stopped, when it measured samples on one scan line of a scan along their
  // voxels' normals (a sparse sensor's far façades); unset otherwise.
  std::optional<Matrix4> settled_pose;
  // The share of the settling's in-band samples that lie on one scan line (0 without a sensor).
  double one_scan_line_share = 0.0;
  // The residuals' part that neighbouring inliers share (absolute; the square root of the mean
  // product of neighbours' signed residuals): about 0 for noise.
  double coherent_residual = 0.0;
  // The direction of motion the agreeing samples fix least (rotation axis scaled by its share of
  // the lever, then translation), the pose's standard error along it (absolute: a rotation as
  // the displacement at the samples' RMS radius; infinite when no agreeing sample constrains
  // it), the covered samples' information along it per covered sample, and how many covered
  // samples constrain it most and the share of them that agree.
  double worst_direction_error = 0.0;
  double worst_direction_strength = 0.0;
  int worst_direction_samples = 0;
  double worst_direction_fraction = 0.0;
  Eigen::Matrix<double, 6, 1> worst_direction = Eigen::Matrix<double, 6, 1>::Zero();
  // The translation the agreeing samples fix least (unit; the least eigenvector of their
  // information's translation block) and the covered samples' information along it per covered
  // sample (as worst_direction_strength): a slide along a corridor or a road, which the worst
  // direction need not be (a roll about the corridor's axis can be weaker still).
  Vec3 weakest_translation = Vec3::Zero();
  double weakest_translation_strength = 0.0;
  // The frame of worst_direction: the covered samples' centre (in the target's frame) and their
  // RMS distance from it (the lever that turns a rotation into a displacement).
  Vec3 direction_centre = Vec3::Zero();
  double direction_lever = 1.0;
  // The agreeing samples' median angle between their normal and the target's, and the covered
  // samples left out of the directional test as sitting on sharp edges (see feature_angle_*).
  double normal_angle_median_deg = 0.0;
  int edge_samples = 0;
  // The pose's covariance: the small motion exp(xi) that would take the pose to the truth, xi =
  // (rotation vector in radians, translation) in the target's frame about its origin, has this
  // covariance under the agreeing samples' evidence (the point-to-plane information their source
  // and target normals share, and the inliers' residuals with the part neighbours share:
  // PoseCovariance). Empty
  // when some direction of motion carries no such information. A covariance alone does not say
  // a pose is right (a wrong pose can fit its wrong partners precisely): read it with the
  // verdict.
  std::optional<Eigen::Matrix<double, 6, 6>> pose_covariance;
  // Its extent, 1 sigma along the least certain direction: a rotation (degrees), and a
  // translation at the covered samples' centre (direction_centre), where the two do not mix.
  double pose_rotation_sigma_deg = 0.0;
  double pose_translation_sigma = 0.0;
  Verdict verdict = Verdict::kTooLittleOverlap;

  bool verified() const { return verdict == Verdict::kVerified; }
  // covered / samples: the share of the source the pose lays over the target's data.
  double covered_fraction() const { return samples > 0 ? double(covered) / samples : 0.0; }
  // covered / (samples - hidden): the share of what the target's sensor could see of the source
  // that the pose lays over the target's data (covered_fraction when no sensor is known).
  double visible_covered_fraction() const {
    return samples > hidden ? double(covered) / (samples - hidden) : 0.0;
  }
  // inliers / (samples - hidden): the share of what the target's sensor could see of the source
  // that the pose explains (explained_fraction when no sensor is known). A pose slid along a
  // street or a corridor moves samples beyond the target's range or above its top beam, where no
  // pose could explain them; this share does not count them against it.
  double visible_explained_fraction() const {
    return samples > hidden ? double(inliers) / (samples - hidden) : 0.0;
  }
  // seen_through / (samples - hidden): the share of what the target's sensor could judge that it
  // saw through.
  double seen_through_fraction() const {
    return samples > hidden ? double(seen_through) / (samples - hidden) : 0.0;
  }
  // seen_from_behind / sides_judged.
  double seen_from_behind_fraction() const {
    return sides_judged > 0 ? double(seen_from_behind) / sides_judged : 0.0;
  }
  // "translation along (0.99, 0.11, 0.02)" or "rotation about (...)".
  std::string WorstDirectionText() const;
};

// The clouds' estimated noise sigmas (absolute units).
struct NoiseLevels {
  double target = 0.0;
  double source = 0.0;
};

// What one verification leaves for the next of the same samples on the same target: each
// sample's nearest target voxels, MLS anchors and target points (NeighborCaches, which answer
// exactly as the trees do). A pose and its refinement land the samples close to where they
// landed before, so the second verification finds most neighbours without searching. The score
// is the same with or without it. One per sample set; one verification at a time.
struct VerificationCaches {
  struct Sample {
    NeighborCache<8> voxels;
    MlsPatches::AnchorCache anchors;  // around the sample
    NeighborCache<16> samples;        // where the patches do not reach: the local plane's samples
  };
  const Target* target = nullptr;  // whose caches they are
  std::vector<Sample> samples;
};

// Scores `transform` (source to target) by the source's voxel cloud `samples` (a sample without
// a normal takes no part in the directional test). A sample's expected residual combines the
// target's noise where it lands (its estimate, or the local spread there when larger) with the
// source's noise averaged over the sample's voxel. Thread-safe; `threads` find where the samples
// land, and the sums run in sample order, so the score is the same for any count.
VerificationScore VerifyAlignment(const Target& target, const VoxelCloud& samples,
                                  const Matrix4& transform, const NoiseLevels& noise,
                                  const VerificationOptions& options = {}, int threads = 1,
                                  VerificationCaches* caches = nullptr);

// What Register measures of a source for the verdict: its noise sigma (units of the target's
// d) and, where the target's sensor is known, the source's own (FindScanSensor), for the test of
// the sides the two sensors saw each surface from.
struct SourceMeasures {
  double noise_d = 0.0;
  std::optional<Vec3> sensor;
};
SourceMeasures MeasureSource(const Target& target, const PointCloud& source, int threads = 1);

// A pose's covariance from point-to-plane evidence gathered about `centre`, over the parameters
// (rotation vector times `lever`, translation at `centre`): the sandwich A^-1 B A^-1 of the
// `information` A and the `gradient_spread` B, the covariance of the gradient sum_i J_i r_i
// (s^2 A for independent residuals of variance s^2; larger where neighbours share residuals).
// Returned for xi = (rotation vector, translation at the origin), as
// VerificationScore::pose_covariance; empty when `information` is not positive definite.
std::optional<Eigen::Matrix<double, 6, 6>> PoseCovariance(
    const Eigen::Matrix<double, 6, 6>& information,
    const Eigen::Matrix<double, 6, 6>& gradient_spread, const Vec3& centre, double lever);
// The source's sensor alone, on its index `tree`: none when the target shows no sensor (the
// test needs both) or the source's sampling shows none.
std::optional<Vec3> SourceSensor(const Target& target, const PointCloud& source, const KdTree& tree,
                                 int threads = 1);

// Verifies `transform` (source to target) as Register verifies a result: the source measured
// (MeasureSource) and its voxel cloud at the target's working voxel scored.
VerificationScore VerifyPose(const Target& target, const PointCloud& source,
                             const Matrix4& transform, int threads = 1);

// `transform` followed by a motion along `score`'s worst direction that moves the covered samples
// by about `distance` (a translation moves each by exactly that; a rotation about the samples'
// centre moves them by that at their RMS radius).
Matrix4 MovedAlongWorstDirection(const VerificationScore& score, const Matrix4& transform,
                                 double distance);
// The same along `direction` (rotation scaled by the lever, then translation, as worst_direction)
// in `score`'s frame: the rival search also probes the weakest translation.
Matrix4 MovedAlong(const VerificationScore& score, const Eigen::Matrix<double, 6, 1>& direction,
                   const Matrix4& transform, double distance);

// A verified `score` whose pose a longer settling than its own (method auto's finish, over every
// source point) moved by `displacement`, to a pose that did not verify: the settling says where
// the data put the pose, and beyond the verdict's settling bound (max_settle_sigmas noise sigmas
// of the band, at least min_band_spacings of `median_spacing`) the pose is not there. Then the
// score becomes `pulled` with that displacement as its settling, and true is returned; otherwise
// it is left as it is.
bool PulledBySettling(VerificationScore& score, double displacement, double median_spacing,
                      const VerificationOptions& options = {});

// Whether `a` explains the source better than `b` (ranks candidate poses): the verdict first,
// then more inliers by at least 1 % (within that, two poses are the same answer).
bool BetterScore(const VerificationScore& a, const VerificationScore& b);

// The distance of each of `points` (in the target's frame) to the target's MLS surface: to its
// projection by the target's MLS patches, or to the nearest target sample where no patch reaches
// (or the target has none). Absolute units.
std::vector<double> DistancesToMlsSurface(const Target& target, const std::vector<Vec3>& points);

}  // namespace mlsreg
