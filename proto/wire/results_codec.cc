#include "mlsreg/wire/results_codec.h"

#include "mlsreg/wire/enum_codec.h"
#include "mlsreg/wire/transform_codec.h"

namespace mlsreg::wire {

v1::Termination TerminationToProto(Termination t) {
  return static_cast<v1::Termination>(EnumToWire(TerminationNames(), static_cast<int>(t)));
}

Termination TerminationFromProto(v1::Termination t) {
  return EnumFromWire(TerminationNames(), t, Termination::kMaxIterations, "termination")
      .value_or(Termination::kMaxIterations);
}

void ToProto(const VerificationScore& s, v1::VerificationScore* out) {
  out->set_samples(s.samples);
  out->set_inliers(s.inliers);
  out->set_inlier_fraction(s.inlier_fraction);
  out->set_rmse_d(s.rmse_d);
  out->set_inlier_distance_d(s.inlier_distance_d);
  out->set_verdict(
      static_cast<v1::Verdict>(EnumToWire(VerdictNames(), static_cast<int>(s.verdict))));
  out->set_covered(s.covered);
  out->set_hidden(s.hidden);
  out->set_seen_through(s.seen_through);
  out->set_sides_judged(s.sides_judged);
  out->set_seen_from_behind(s.seen_from_behind);
  out->set_explained_fraction(s.explained_fraction);
  out->set_inlier_distance(s.inlier_distance);
  for (int k = 0; k < 6; ++k) out->add_worst_direction(s.worst_direction[k]);
  out->set_worst_direction_fraction(s.worst_direction_fraction);
  out->set_worst_direction_samples(s.worst_direction_samples);
  out->set_worst_direction_strength(s.worst_direction_strength);
  out->set_worst_direction_error(s.worst_direction_error);
  for (int k = 0; k < 3; ++k) out->add_weakest_translation(s.weakest_translation[k]);
  out->set_weakest_translation_strength(s.weakest_translation_strength);
  out->set_residual_scale(s.residual_scale);
  out->set_pull_fraction(s.pull_fraction);
  out->set_pull_rotation_deg(s.pull_rotation_deg);
  out->set_pull_translation(s.pull_translation);
  out->set_pull_displacement(s.pull_displacement);
  out->set_settle_displacement(s.settle_displacement);
  out->set_coherent_residual(s.coherent_residual);
  out->set_normal_angle_median_deg(s.normal_angle_median_deg);
  out->set_edge_samples(s.edge_samples);
  out->set_noise(s.noise);
  if (s.pose_covariance) {
    for (int row = 0; row < 6; ++row) {
      for (int col = 0; col < 6; ++col) out->add_pose_covariance((*s.pose_covariance)(row, col));
    }
  }
  out->set_pose_rotation_sigma_deg(s.pose_rotation_sigma_deg);
  out->set_pose_translation_sigma(s.pose_translation_sigma);
}

VerificationScore FromProto(const v1::VerificationScore& p) {
  VerificationScore s;
  s.samples = p.samples();
  s.inliers = p.inliers();
  s.inlier_fraction = p.inlier_fraction();
  s.rmse_d = p.rmse_d();
  s.inlier_distance_d = p.inlier_distance_d();
  s.verdict = EnumFromWire(VerdictNames(), p.verdict(), Verdict::kTooLittleOverlap, "verdict")
                  .value_or(Verdict::kTooLittleOverlap);
  s.covered = p.covered();
  s.hidden = p.hidden();
  s.seen_through = p.seen_through();
  s.sides_judged = p.sides_judged();
  s.seen_from_behind = p.seen_from_behind();
  s.explained_fraction = p.explained_fraction();
  s.inlier_distance = p.inlier_distance();
  for (int k = 0; k < 6 && k < p.worst_direction_size(); ++k) {
    s.worst_direction[k] = p.worst_direction(k);
  }
  s.worst_direction_fraction = p.worst_direction_fraction();
  s.worst_direction_samples = p.worst_direction_samples();
  s.worst_direction_strength = p.worst_direction_strength();
  s.worst_direction_error = p.worst_direction_error();
  for (int k = 0; k < 3 && k < p.weakest_translation_size(); ++k) {
    s.weakest_translation[k] = p.weakest_translation(k);
  }
  s.weakest_translation_strength = p.weakest_translation_strength();
  s.residual_scale = p.residual_scale();
  s.pull_fraction = p.pull_fraction();
  s.pull_rotation_deg = p.pull_rotation_deg();
  s.pull_translation = p.pull_translation();
  s.pull_displacement = p.pull_displacement();
  s.settle_displacement = p.settle_displacement();
  s.coherent_residual = p.coherent_residual();
  s.normal_angle_median_deg = p.normal_angle_median_deg();
  s.edge_samples = p.edge_samples();
  if (p.pose_covariance_size() == 36) {
    Eigen::Matrix<double, 6, 6> covariance;
    for (int k = 0; k < 36; ++k) covariance(k / 6, k % 6) = p.pose_covariance(k);
    s.pose_covariance = covariance;
  }
  s.pose_rotation_sigma_deg = p.pose_rotation_sigma_deg();
  s.pose_translation_sigma = p.pose_translation_sigma();
  s.noise = p.noise();
  return s;
}

namespace {

void CandidateToProto(const AutoCandidate& c, v1::AutoCandidate* p) {
  p->set_origin(static_cast<v1::CandidateOrigin>(
      EnumToWire(CandidateOriginNames(), static_cast<int>(c.origin))));
  wire::ToProto(c.start, p->mutable_start());
  wire::ToProto(c.refined, p->mutable_refined());
  p->set_feature_inliers(c.feature_inliers);
  p->set_iterations(c.iterations);
  ToProto(c.score, p->mutable_score());
  p->set_seconds(c.seconds);
  p->set_in_start_basin(c.in_start_basin);
}

AutoCandidate CandidateFromProto(const v1::AutoCandidate& c) {
  AutoCandidate a;
  a.origin = EnumFromWire(CandidateOriginNames(), c.origin(), CandidateOrigin::kStart, "origin")
                 .value_or(CandidateOrigin::kStart);
  a.start = ReportedFromProto(c.start());
  a.refined = ReportedFromProto(c.refined());
  a.feature_inliers = c.feature_inliers();
  a.iterations = c.iterations();
  a.score = FromProto(c.score());
  a.seconds = c.seconds();
  a.in_start_basin = c.in_start_basin();
  return a;
}

void AutoReportToProto(const AutoReport& r, v1::AutoReport* out) {
  for (const AutoCandidate& c : r.candidates) CandidateToProto(c, out->add_candidates());
  out->set_chosen(r.chosen);
  out->set_verified(r.verified);
  ToProto(r.verification, out->mutable_verification());
  out->set_early_exit(r.early_exit);
  out->set_feature_matches(r.feature_matches);
  out->set_start_seconds(r.timings.start);
  out->set_global_seconds(r.timings.global);
  out->set_candidates_seconds(r.timings.candidates);
  out->set_final_seconds(r.timings.final);
  out->set_rivals_seconds(r.timings.rivals);
  if (r.rival) out->set_rival(*r.rival);
  out->set_polished_by_settling(r.polished_by_settling);
  v1::FinishReport* finish = out->mutable_finish();
  finish->set_kind(
      static_cast<v1::FinishKind>(EnumToWire(FinishKindNames(), static_cast<int>(r.finish.kind))));
  finish->set_noise_sigma_d(r.finish.noise_d);
  finish->set_crossover_d(r.finish.crossover_d);
  finish->set_samples(r.finish.samples);
  finish->set_iterations(r.finish.iterations);
  finish->set_kept(r.finish.kept);
  finish->set_moved(r.finish.moved);
  finish->set_contradicted(r.finish.contradicted);
  finish->set_seconds(r.finish.seconds);
}

AutoReport AutoReportFromProto(const v1::AutoReport& p) {
  AutoReport r;
  for (const v1::AutoCandidate& c : p.candidates()) r.candidates.push_back(CandidateFromProto(c));
  r.chosen = p.chosen();
  r.verified = p.verified();
  r.verification = FromProto(p.verification());
  r.early_exit = p.early_exit();
  r.feature_matches = p.feature_matches();
  r.timings = {p.start_seconds(), p.global_seconds(), p.candidates_seconds(), p.final_seconds(),
               p.rivals_seconds()};
  if (p.has_rival()) r.rival = p.rival();
  r.polished_by_settling = p.polished_by_settling();
  const v1::FinishReport& finish = p.finish();
  r.finish.kind = EnumFromWire(FinishKindNames(), finish.kind(), FinishKind::kNone, "finish.kind")
                      .value_or(FinishKind::kNone);
  r.finish.noise_d = finish.noise_sigma_d();
  r.finish.crossover_d = finish.crossover_d();
  r.finish.samples = finish.samples();
  r.finish.iterations = finish.iterations();
  r.finish.kept = finish.kept();
  r.finish.moved = finish.moved();
  r.finish.contradicted = finish.contradicted();
  r.finish.seconds = finish.seconds();
  return r;
}

}  // namespace

void ToProto(const IterationReport& r, v1::Progress* out) {
  out->set_iteration(r.iteration);
  ToProto(r.transform, out->mutable_transform());
  out->set_rmse(r.rmse);
  out->set_rmse_d(r.rmse_d);
  v1::CorrespondenceCounts* c = out->mutable_counts();
  c->set_matched(r.counts.matched);
  c->set_rejected_normal(r.counts.rejected_normal);
  c->set_rejected_curvature(r.counts.rejected_curvature);
  c->set_rejected_distance(r.counts.rejected_distance);
  c->set_invalid(r.counts.invalid);
  out->set_admm_iterations(r.admm_iterations);
  out->set_elapsed_seconds(r.elapsed_seconds);
  out->set_stage(static_cast<v1::Stage>(EnumToWire(StageNames(), static_cast<int>(r.stage))));
  out->set_candidate(r.candidate);
}

IterationReport FromProto(const v1::Progress& p) {
  IterationReport r;
  r.iteration = p.iteration();
  r.transform = ReportedFromProto(p.transform());
  r.rmse = p.rmse();
  r.rmse_d = p.rmse_d();
  r.counts.matched = p.counts().matched();
  r.counts.rejected_normal = p.counts().rejected_normal();
  r.counts.rejected_curvature = p.counts().rejected_curvature();
  r.counts.rejected_distance = p.counts().rejected_distance();
  r.counts.invalid = p.counts().invalid();
  r.admm_iterations = p.admm_iterations();
  r.elapsed_seconds = p.elapsed_seconds();
  r.stage = EnumFromWire(StageNames(), p.stage(), Stage::kSingle, "stage").value_or(Stage::kSingle);
  r.candidate = p.candidate();
  return r;
}

void ToProto(const RegistrationResult& r, v1::Result* out) {
  ToProto(r.transform, out->mutable_transform());
  out->set_converged(r.converged);
  out->set_termination(TerminationToProto(r.termination));
  out->set_iterations(r.iterations);
  v1::Timings* t = out->mutable_timings();
  t->set_preprocessing_seconds(r.timings.preprocessing);
  t->set_subsampling_seconds(r.timings.subsampling);
  t->set_matching_seconds(r.timings.matching);
  t->set_optimisation_seconds(r.timings.optimisation);
  t->set_registration_seconds(r.timings.total);
  out->set_sampling_distance(r.sampling_distance);
  out->set_num_samples(r.num_samples);
  out->set_mls_radius_d(r.mls_radius_d);
  out->set_mls_radius_auto(r.mls_radius_auto);
  out->set_target_noise_sigma_d(r.target_noise_d);
  out->set_source_noise_sigma_d(r.source_noise_d);
  if (r.auto_report) AutoReportToProto(*r.auto_report, out->mutable_auto_report());
  if (r.verification) ToProto(*r.verification, out->mutable_verification());
  if (r.rival) CandidateToProto(*r.rival, out->mutable_rival());
  v1::Scales* scales = out->mutable_scales();
  scales->set_mean_spacing(r.scales.mean_spacing);
  scales->set_median_spacing(r.scales.median_spacing);
  scales->set_spacing_p90(r.scales.spacing_p90);
  scales->set_extent(r.scales.extent);
  scales->set_working_voxel(r.scales.working_voxel);
  scales->set_capture_start(r.scales.capture_start);
  scales->set_capture_end(r.scales.capture_end);
  scales->set_mls_radius(r.scales.mls_radius);
  scales->set_verification_band(r.scales.verification_band);
  if (r.scales.sensor) {
    v1::Vector3* sensor = scales->mutable_sensor();
    sensor->set_x(r.scales.sensor->x());
    sensor->set_y(r.scales.sensor->y());
    sensor->set_z(r.scales.sensor->z());
  }
  for (const UserLength& length : r.scales.user_lengths) {
    v1::UserLength* out_length = scales->add_user_lengths();
    out_length->set_parameter(length.parameter);
    out_length->set_value(length.value);
    out_length->set_value_d(length.value_d);
  }
}

RegistrationResult FromProto(const v1::Result& p) {
  RegistrationResult r;
  r.transform = ReportedFromProto(p.transform());
  r.converged = p.converged();
  r.termination = TerminationFromProto(p.termination());
  r.iterations = p.iterations();
  r.timings.preprocessing = p.timings().preprocessing_seconds();
  r.timings.subsampling = p.timings().subsampling_seconds();
  r.timings.matching = p.timings().matching_seconds();
  r.timings.optimisation = p.timings().optimisation_seconds();
  r.timings.total = p.timings().registration_seconds();
  r.sampling_distance = p.sampling_distance();
  r.num_samples = p.num_samples();
  r.mls_radius_d = p.mls_radius_d();
  r.mls_radius_auto = p.mls_radius_auto();
  r.target_noise_d = p.target_noise_sigma_d();
  r.source_noise_d = p.source_noise_sigma_d();
  if (p.has_auto_report()) r.auto_report = AutoReportFromProto(p.auto_report());
  if (p.has_verification()) r.verification = FromProto(p.verification());
  if (p.has_rival()) r.rival = CandidateFromProto(p.rival());
  const v1::Scales& scales = p.scales();
  r.scales = {scales.mean_spacing(), scales.median_spacing(), scales.spacing_p90(),
              scales.extent(),       scales.working_voxel(),  scales.capture_start(),
              scales.capture_end(),  scales.mls_radius(),     scales.verification_band()};
  for (const v1::UserLength& length : scales.user_lengths()) {
    r.scales.user_lengths.push_back({length.parameter(), length.value(), length.value_d()});
  }
  if (scales.has_sensor()) {
    r.scales.sensor = Vec3(scales.sensor().x(), scales.sensor().y(), scales.sensor().z());
  }
  return r;
}

void ToProto(const PoseError& error, v1::GroundTruthError* out) {
  out->set_rmse_d(error.rmse_d);
  out->set_success(error.success);
  out->set_rotation_error_deg(error.rotation_deg);
  out->set_translation_error_d(error.translation_d);
}

PoseError FromProto(const v1::GroundTruthError& error) {
  return PoseError{error.rmse_d(), error.success(), error.rotation_error_deg(),
                   error.translation_error_d()};
}

}  // namespace mlsreg::wire
