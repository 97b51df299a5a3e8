#include "mlsreg/wire/align_codec.h"

#include "absl/strings/str_cat.h"
#include "mlsreg/wire/enum_codec.h"
#include "mlsreg/wire/options_codec.h"
#include "mlsreg/wire/results_codec.h"
#include "mlsreg/wire/transform_codec.h"

namespace mlsreg::wire {

absl::StatusOr<AlignOptions> AlignOptionsFromProto(const v1::AlignScansHeader& header) {
  AlignOptions options;
  auto pairs = EnumFromWire(PairPolicyNames(), header.pairs(), options.pairs, "header.pairs");
  if (!pairs.ok()) return pairs.status();
  options.pairs = *pairs;
  // METHOD_UNSPECIFIED is auto, as for a registration and as the library's and CLI's default.
  auto edge = OptionsFromProto(header.method(), header.parameters());
  if (!edge.ok()) return edge.status();
  options.edge = *std::move(edge);
  if (header.has_min_overlap()) options.min_overlap = header.min_overlap();
  if (header.has_overlap_distance()) {
    options.overlap_distance = {header.overlap_distance(), true};
  } else if (header.has_overlap_distance_d()) {
    options.overlap_distance = {header.overlap_distance_d(), false};
  }
  options.anchor = header.anchor();
  for (int i = 0; i < header.initial_poses_size(); ++i) {
    auto pose = FromProto(header.initial_poses(i), absl::StrCat("header.initial_poses[", i, "]"));
    if (!pose.ok()) return pose.status();
    options.initial_poses.push_back(*pose);
  }
  return options;
}

void AlignOptionsToProto(const AlignOptions& options, v1::AlignScansHeader* header) {
  header->set_pairs(
      static_cast<v1::PairPolicy>(EnumToWire(PairPolicyNames(), static_cast<int>(options.pairs))));
  v1::Method method;
  OptionsToProto(options.edge, &method, header->mutable_parameters());
  header->set_method(method);
  header->set_min_overlap(options.min_overlap);
  if (options.overlap_distance.absolute) {
    header->set_overlap_distance(options.overlap_distance.value);
  } else {
    header->set_overlap_distance_d(options.overlap_distance.value);
  }
  header->set_anchor(options.anchor);
  header->clear_initial_poses();
  for (const Matrix4& pose : options.initial_poses) ToProto(pose, header->add_initial_poses());
}

void ToProto(const AlignEdge& edge, v1::AlignEdge* out) {
  out->set_from(edge.from);
  out->set_to(edge.to);
  ToProto(edge.relative, out->mutable_relative());
  out->set_overlap(edge.overlap);
  out->set_correspondences(edge.correspondences);
  out->set_termination(TerminationToProto(edge.registration.termination));
  out->set_iterations(edge.registration.iterations);
  out->set_registration_seconds(edge.registration.timings.total);
  out->set_trusted(edge.trusted);
  out->set_kept(edge.kept);
  out->set_residual_before_d(edge.residual_before_d);
  out->set_residual_after_d(edge.residual_after_d);
  if (!edge.registration.trace.empty()) out->set_rmse_d(edge.registration.trace.back().rmse_d);
  ToProto(edge.verification, out->mutable_verification());
}

AlignEdge FromProto(const v1::AlignEdge& p) {
  AlignEdge edge;
  edge.from = p.from();
  edge.to = p.to();
  edge.relative = ReportedFromProto(p.relative());
  edge.registration.transform = edge.relative;
  edge.overlap = p.overlap();
  edge.correspondences = p.correspondences();
  edge.registration.termination = TerminationFromProto(p.termination());
  edge.registration.converged = edge.registration.termination == Termination::kConverged;
  edge.registration.iterations = p.iterations();
  edge.registration.timings.total = p.registration_seconds();
  edge.trusted = p.trusted();
  edge.kept = p.kept();
  edge.residual_before_d = p.residual_before_d();
  edge.residual_after_d = p.residual_after_d();
  edge.verification = FromProto(p.verification());
  edge.registration.verification = edge.verification;
  IterationReport last;
  last.iteration = p.iterations();
  last.rmse_d = p.rmse_d();
  last.transform = edge.relative;
  edge.registration.trace.push_back(last);
  return edge;
}

void ToProto(const AlignResult& r, v1::AlignScansResult* out) {
  for (const Matrix4& pose : r.poses) ToProto(pose, out->add_poses());
  for (const Matrix4& pose : r.chained_poses) ToProto(pose, out->add_chained_poses());
  for (const AlignEdge& edge : r.edges) ToProto(edge, out->add_edges());
  for (double d : r.chain_deviation_d) out->add_chain_deviation_d(d);
  out->set_loop_closure_rotation_deg(r.loop_closure_rotation_deg);
  out->set_loop_closure_error_d(r.loop_closure_error_d);
  out->set_sampling_distance(r.sampling_distance);
  out->set_graph_iterations(r.graph_iterations);
  out->set_covariance_weighted_edges(r.covariance_weighted_edges);
  for (const std::optional<Matrix6>& c : r.pose_covariances) {
    v1::ScanPoseCovariance* values = out->add_pose_covariances();
    if (!c) continue;
    for (int k = 0; k < 36; ++k) values->add_values((*c)(k / 6, k % 6));
  }
  out->set_seconds(r.seconds);
  out->set_loop_closure_exceeded(r.loop_closure_exceeded);
  for (int i : r.unverified_scans) out->add_unverified_scans(i);
}

AlignResult FromProto(const v1::AlignScansResult& p) {
  AlignResult r;
  for (const v1::Transform& t : p.poses()) r.poses.push_back(ReportedFromProto(t));
  for (const v1::Transform& t : p.chained_poses()) r.chained_poses.push_back(ReportedFromProto(t));
  for (const v1::AlignEdge& e : p.edges()) r.edges.push_back(FromProto(e));
  r.chain_deviation_d.assign(p.chain_deviation_d().begin(), p.chain_deviation_d().end());
  r.loop_closure_rotation_deg = p.loop_closure_rotation_deg();
  r.loop_closure_error_d = p.loop_closure_error_d();
  r.sampling_distance = p.sampling_distance();
  r.graph_iterations = p.graph_iterations();
  r.covariance_weighted_edges = p.covariance_weighted_edges();
  for (const v1::ScanPoseCovariance& values : p.pose_covariances()) {
    std::optional<Matrix6>& c = r.pose_covariances.emplace_back();
    if (values.values_size() != 36) continue;
    c.emplace();
    for (int k = 0; k < 36; ++k) (*c)(k / 6, k % 6) = values.values(k);
  }
  r.seconds = p.seconds();
  r.loop_closure_exceeded = p.loop_closure_exceeded();
  r.unverified_scans.assign(p.unverified_scans().begin(), p.unverified_scans().end());
  return r;
}

}  // namespace mlsreg::wire
