#include "mlsreg/wire/convert.h"

#include <bit>
#include <cmath>
#include <cstring>

#include "absl/strings/str_cat.h"
#include "mlsreg/geometry/depth_grid.h"

namespace mlsreg::wire {

namespace {
std::string Field(std::string_view field) { return std::string(field); }
}  // namespace

// ------------------------------------------------------------------------------------ status

grpc::Status ToGrpcStatus(const absl::Status& status) {
  if (status.ok()) return grpc::Status::OK;
  return grpc::Status(static_cast<grpc::StatusCode>(status.code()), std::string(status.message()));
}

absl::Status ToAbslStatus(const grpc::Status& status) {
  if (status.ok()) return absl::OkStatus();
  return absl::Status(static_cast<absl::StatusCode>(status.error_code()), status.error_message());
}

// ------------------------------------------------------------------------------------ clouds

std::size_t RecordBytes(const v1::CloudHeader& header) {
  std::size_t scalar = 0;
  if (header.scalar_type() == v1::SCALAR_TYPE_FLOAT32) scalar = 4;
  if (header.scalar_type() == v1::SCALAR_TYPE_FLOAT64) scalar = 8;
  return scalar * (header.has_normals() ? 6 : 3);
}

absl::StatusOr<std::uint64_t> CheckCloudHeader(const v1::CloudHeader& header,
                                               std::uint64_t max_points, std::string_view field) {
  const std::string f = Field(field);
  if (header.scalar_type() != v1::SCALAR_TYPE_FLOAT32 &&
      header.scalar_type() != v1::SCALAR_TYPE_FLOAT64) {
    return absl::InvalidArgumentError(absl::StrCat(f,
                                                   ".scalar_type: must be FLOAT32 or FLOAT64 (got ",
                                                   static_cast<int>(header.scalar_type()), ")"));
  }
  if (header.point_count() == 0) {
    return absl::InvalidArgumentError(f + ".point_count: the cloud has no points");
  }
  if (header.point_count() > max_points) {
    return absl::InvalidArgumentError(absl::StrCat(f, ".point_count: ", header.point_count(),
                                                   " points exceed the limit of ", max_points));
  }
  if (header.has_viewpoint()) {
    const v1::Vector3& v = header.viewpoint();
    if (!std::isfinite(v.x()) || !std::isfinite(v.y()) || !std::isfinite(v.z())) {
      return absl::InvalidArgumentError(f + ".viewpoint: non-finite coordinate");
    }
  }
  if (header.has_intrinsics()) {
    const v1::PinholeIntrinsics& k = header.intrinsics();
    if (absl::Status s = ValidateIntrinsicsFor(
            PinholeIntrinsics{k.width(), k.height(), k.fx(), k.fy(), k.cx(), k.cy()},
            header.point_count(), f + ".intrinsics");
        !s.ok()) {
      return s;
    }
  }
  return header.point_count() * RecordBytes(header);
}

namespace {
template <typename Scalar>
Scalar LoadLittleEndian(const char* p) {
  Scalar value;
  std::memcpy(&value, p, sizeof(Scalar));
  if constexpr (std::endian::native == std::endian::big) {
    auto* bytes = reinterpret_cast<unsigned char*>(&value);
    for (std::size_t i = 0; i < sizeof(Scalar) / 2; ++i) {
      std::swap(bytes[i], bytes[sizeof(Scalar) - 1 - i]);
    }
  }
  return value;
}

template <typename Scalar>
void StoreLittleEndian(Scalar value, std::string* out) {
  char bytes[sizeof(Scalar)];
  std::memcpy(bytes, &value, sizeof(Scalar));
  if constexpr (std::endian::native == std::endian::big) {
    for (std::size_t i = 0; i < sizeof(Scalar) / 2; ++i) {
      std::swap(bytes[i], bytes[sizeof(Scalar) - 1 - i]);
    }
  }
  out->append(bytes, sizeof(Scalar));
}

template <typename Scalar>
absl::StatusOr<PointCloud> DecodeRecords(const v1::CloudHeader& header, std::string_view payload,
                                         const std::string& field) {
  const std::size_t n = header.point_count();
  const int per_point = header.has_normals() ? 6 : 3;
  PointCloud cloud;
  cloud.points.resize(n);
  if (header.has_normals()) cloud.normals.resize(n);
  const char* p = payload.data();
  for (std::size_t i = 0; i < n; ++i) {
    double v[6];
    for (int k = 0; k < per_point; ++k, p += sizeof(Scalar)) v[k] = LoadLittleEndian<Scalar>(p);
    cloud.points[i] = Vec3(v[0], v[1], v[2]);
    if (!cloud.points[i].allFinite()) {
      return absl::InvalidArgumentError(
          absl::StrCat(field, ".points[", i, "]: non-finite coordinate (NaN or Inf)"));
    }
    if (header.has_normals()) {
      const Vec3 normal(v[3], v[4], v[5]);
      const double length = normal.norm();
      if (!std::isfinite(length) || length <= 0.0) {
        return absl::InvalidArgumentError(
            absl::StrCat(field, ".normals[", i, "]: zero or non-finite normal"));
      }
      cloud.normals[i] = normal / length;
    }
  }
  if (header.has_viewpoint()) {
    cloud.viewpoint = Vec3(header.viewpoint().x(), header.viewpoint().y(), header.viewpoint().z());
  }
  if (header.has_intrinsics()) {
    const v1::PinholeIntrinsics& k = header.intrinsics();
    cloud.intrinsics = PinholeIntrinsics{k.width(), k.height(), k.fx(), k.fy(), k.cx(), k.cy()};
  }
  return cloud;
}
}  // namespace

absl::StatusOr<PointCloud> DecodeCloud(const v1::CloudHeader& header, std::string_view payload,
                                       std::string_view field) {
  const std::string f = Field(field);
  auto expected = CheckCloudHeader(header, std::numeric_limits<std::uint64_t>::max(), field);
  if (!expected.ok()) return expected.status();
  if (payload.size() != *expected) {
    return absl::InvalidArgumentError(
        absl::StrCat(f, ": ", header.point_count(), " points of ", RecordBytes(header),
                     " bytes need ", *expected, " bytes, but ", payload.size(), " bytes arrived"));
  }
  if (header.scalar_type() == v1::SCALAR_TYPE_FLOAT32) {
    return DecodeRecords<float>(header, payload, f);
  }
  return DecodeRecords<double>(header, payload, f);
}

void EncodeCloud(const PointCloud& cloud, v1::ScalarType scalar_type, v1::CloudHeader* header,
                 std::string* payload) {
  header->Clear();
  header->set_point_count(cloud.size());
  header->set_scalar_type(scalar_type);
  header->set_has_normals(cloud.has_normals());
  if (cloud.viewpoint) {
    header->mutable_viewpoint()->set_x(cloud.viewpoint->x());
    header->mutable_viewpoint()->set_y(cloud.viewpoint->y());
    header->mutable_viewpoint()->set_z(cloud.viewpoint->z());
  }
  if (cloud.intrinsics) {
    v1::PinholeIntrinsics* k = header->mutable_intrinsics();
    k->set_width(cloud.intrinsics->width);
    k->set_height(cloud.intrinsics->height);
    k->set_fx(cloud.intrinsics->fx);
    k->set_fy(cloud.intrinsics->fy);
    k->set_cx(cloud.intrinsics->cx);
    k->set_cy(cloud.intrinsics->cy);
  }
  payload->clear();
  payload->reserve(cloud.size() * RecordBytes(*header));
  auto put = [&](double v) {
    if (scalar_type == v1::SCALAR_TYPE_FLOAT32) {
      StoreLittleEndian<float>(static_cast<float>(v), payload);
    } else {
      StoreLittleEndian<double>(v, payload);
    }
  };
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    for (int k = 0; k < 3; ++k) put(cloud.points[i][k]);
    if (cloud.has_normals()) {
      for (int k = 0; k < 3; ++k) put(cloud.normals[i][k]);
    }
  }
}

PayloadAssembler::PayloadAssembler(std::uint64_t expected_bytes, std::size_t max_chunk_bytes,
                                   std::string field)
    : expected_(expected_bytes), max_chunk_bytes_(max_chunk_bytes), field_(std::move(field)) {}

absl::Status PayloadAssembler::EndedEarly() const {
  return absl::InvalidArgumentError(absl::StrCat(
      field_, ": the stream ended after ", payload_.size(), " of ", expected_, " declared bytes"));
}

absl::Status PayloadAssembler::Append(const v1::CloudChunk& chunk) {
  // Checked before appending: the limit is what keeps one message's memory bounded.
  if (chunk.data().size() > max_chunk_bytes_) {
    return absl::InvalidArgumentError(absl::StrCat(field_, ".data: ", chunk.data().size(),
                                                   " bytes exceed the limit of ", max_chunk_bytes_,
                                                   " bytes per chunk"));
  }
  if (chunk.offset() != payload_.size()) {
    return absl::InvalidArgumentError(
        absl::StrCat(field_, ".offset: chunk at byte ", chunk.offset(),
                     " arrived out of order (expected ", payload_.size(), ")"));
  }
  if (payload_.size() + chunk.data().size() > expected_) {
    return absl::InvalidArgumentError(
        absl::StrCat(field_, ".data: ", payload_.size() + chunk.data().size(),
                     " bytes exceed the declared ", expected_, " bytes"));
  }
  // Doubling keeps appends amortised O(1); capping at the total keeps the buffer exact.
  const std::size_t needed = payload_.size() + chunk.data().size();
  if (needed > payload_.capacity()) {
    payload_.reserve(static_cast<std::size_t>(
        std::min<std::uint64_t>(expected_, std::max(needed, 2 * payload_.capacity()))));
  }
  payload_.append(chunk.data());
  return absl::OkStatus();
}

// ------------------------------------------------------------------------------------ transforms

void ToProto(const Matrix4& m, v1::Transform* out) {
  out->clear_row_major();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) out->add_row_major(m(r, c));
  }
}

absl::StatusOr<Matrix4> FromProto(const v1::Transform& t, std::string_view field) {
  const std::string f = Field(field);
  if (t.row_major_size() != 16) {
    return absl::InvalidArgumentError(
        absl::StrCat(f, ": needs 16 row-major numbers, got ", t.row_major_size()));
  }
  Matrix4 m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = t.row_major(4 * r + c);
  }
  if (absl::Status s = CheckRigid(m, f); !s.ok()) return s;
  return m;
}

// ------------------------------------------------------------------------------------ options

std::string_view MethodName(v1::Method method) {
  auto m = MethodFromProto(method);
  return m.ok() ? mlsreg::MethodName(*m) : "";
}

absl::StatusOr<Method> MethodFromProto(v1::Method method) {
  switch (method) {
    case v1::METHOD_UNSPECIFIED:
    case v1::METHOD_MLS_SICP:
      return Method::kMlsSicp;
    case v1::METHOD_CP_SICP:
      return Method::kCpSicp;
    case v1::METHOD_ST_SICP:
      return Method::kStSicp;
    case v1::METHOD_CP_SICP_THEN_MLS_SICP:
      return Method::kCpThenMlsSicp;
    case v1::METHOD_G_ICP:
      return Method::kGicp;
    case v1::METHOD_FGR:
      return Method::kFgr;
    case v1::METHOD_RC_BL:
      return Method::kRcBl;
    case v1::METHOD_RC_P:
      return Method::kRcP;
    default:
      return absl::InvalidArgumentError(
          absl::StrCat("method: unknown method value ", static_cast<int>(method)));
  }
}

v1::Method MethodToProto(Method method) {
  switch (method) {
    case Method::kCpSicp:
      return v1::METHOD_CP_SICP;
    case Method::kMlsSicp:
      return v1::METHOD_MLS_SICP;
    case Method::kStSicp:
      return v1::METHOD_ST_SICP;
    case Method::kCpThenMlsSicp:
      return v1::METHOD_CP_SICP_THEN_MLS_SICP;
    case Method::kGicp:
      return v1::METHOD_G_ICP;
    case Method::kFgr:
      return v1::METHOD_FGR;
    case Method::kRcBl:
      return v1::METHOD_RC_BL;
    case Method::kRcP:
      return v1::METHOD_RC_P;
  }
  return v1::METHOD_UNSPECIFIED;
}

absl::StatusOr<RegistrationOptions> OptionsFromProto(v1::Method method,
                                                     const v1::RegistrationParameters& p) {
  RegistrationOptions o;
  auto m = MethodFromProto(method);
  if (!m.ok()) return m.status();
  o.method = *m;
  if (p.has_num_samples()) o.num_samples = p.num_samples();
  if (p.has_seed()) o.seed = p.seed();
  if (p.has_max_iterations()) o.max_iterations = p.max_iterations();
  if (p.has_convergence_d()) o.convergence_d = p.convergence_d();
  if (p.has_coarse_convergence_d()) o.coarse_convergence_d = p.coarse_convergence_d();
  if (p.has_stall_d()) o.stall_d = p.stall_d();
  if (p.has_tangential_damping()) o.tangential_damping = p.tangential_damping();
  switch (p.coarse_phase_filters()) {
    case v1::COARSE_PHASE_FILTERS_NORMAL:
      o.filter.coarse_phase = CoarsePhaseFilters::kNormal;
      break;
    case v1::COARSE_PHASE_FILTERS_UNSPECIFIED:
    case v1::COARSE_PHASE_FILTERS_ALL:
      o.filter.coarse_phase = CoarsePhaseFilters::kAll;
      break;
    case v1::COARSE_PHASE_FILTERS_NONE:
      o.filter.coarse_phase = CoarsePhaseFilters::kNone;
      break;
    default:
      return absl::InvalidArgumentError(
          absl::StrCat("parameters.coarse_phase_filters: unknown value ",
                       static_cast<int>(p.coarse_phase_filters())));
  }
  if (p.has_mls_radius_d()) o.mls.radius_d = p.mls_radius_d();
  if (p.has_mls_polynomial_degree()) o.mls.polynomial_degree = p.mls_polynomial_degree();
  if (p.has_mls_max_iterations()) o.mls.max_iterations = p.mls_max_iterations();
  if (p.has_mls_warm_start()) o.mls.warm_start = p.mls_warm_start();
  switch (p.mls_far_queries()) {
    case v1::FAR_QUERY_POLICY_UNSPECIFIED:
    case v1::FAR_QUERY_POLICY_SEED_UNTIL_CONVERGED:
      o.mls.far_queries = FarQueryPolicy::kSeedUntilConverged;
      break;
    case v1::FAR_QUERY_POLICY_SEED:
      o.mls.far_queries = FarQueryPolicy::kSeed;
      break;
    case v1::FAR_QUERY_POLICY_DROP:
      o.mls.far_queries = FarQueryPolicy::kDrop;
      break;
    default:
      return absl::InvalidArgumentError(absl::StrCat("parameters.mls_far_queries: unknown value ",
                                                     static_cast<int>(p.mls_far_queries())));
  }
  if (p.has_min_normal_dot()) o.filter.min_normal_dot = p.min_normal_dot();
  if (p.has_min_curvature_ratio()) o.filter.min_curvature_ratio = p.min_curvature_ratio();
  if (p.has_max_distance_d()) o.filter.max_distance_d = p.max_distance_d();
  if (p.has_sicp_p()) o.sicp.p = p.sicp_p();
  if (p.has_sicp_max_outer()) o.sicp.max_outer = p.sicp_max_outer();
  if (p.has_sicp_length_unit_d()) o.sicp_length_unit_d = p.sicp_length_unit_d();
  if (p.has_gicp_covariance_neighbors()) {
    o.gicp.covariance_neighbors = p.gicp_covariance_neighbors();
  }
  if (p.has_gicp_epsilon()) o.gicp.epsilon = p.gicp_epsilon();
  if (p.has_gicp_max_distance_d()) o.gicp.max_distance_d = p.gicp_max_distance_d();
  if (p.has_fgr_feature_radius_d()) o.fgr.feature_radius_d = p.fgr_feature_radius_d();
  if (p.has_fgr_samples()) o.fgr.samples = p.fgr_samples();
  switch (p.sicp_metric()) {
    case v1::SICP_METRIC_UNSPECIFIED:
    case v1::SICP_METRIC_POINT_TO_PLANE:
      o.sicp.metric = SicpMetric::kPointToPlane;
      break;
    case v1::SICP_METRIC_POINT_TO_POINT:
      o.sicp.metric = SicpMetric::kPointToPoint;
      break;
    default:
      return absl::InvalidArgumentError(absl::StrCat("parameters.sicp_metric: unknown value ",
                                                     static_cast<int>(p.sicp_metric())));
  }
  if (absl::Status s = ValidateOptions(o); !s.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("parameters.", s.message()));
  }
  return o;
}

void OptionsToProto(const RegistrationOptions& o, v1::Method* method,
                    v1::RegistrationParameters* p) {
  *method = MethodToProto(o.method);
  p->Clear();
  p->set_num_samples(o.num_samples);
  p->set_seed(o.seed);
  p->set_max_iterations(o.max_iterations);
  p->set_convergence_d(o.convergence_d);
  p->set_coarse_convergence_d(o.coarse_convergence_d);
  p->set_stall_d(o.stall_d);
  p->set_tangential_damping(o.tangential_damping);
  switch (o.filter.coarse_phase) {
    case CoarsePhaseFilters::kNormal:
      p->set_coarse_phase_filters(v1::COARSE_PHASE_FILTERS_NORMAL);
      break;
    case CoarsePhaseFilters::kAll:
      p->set_coarse_phase_filters(v1::COARSE_PHASE_FILTERS_ALL);
      break;
    case CoarsePhaseFilters::kNone:
      p->set_coarse_phase_filters(v1::COARSE_PHASE_FILTERS_NONE);
      break;
  }
  p->set_mls_radius_d(o.mls.radius_d);
  p->set_mls_polynomial_degree(o.mls.polynomial_degree);
  p->set_mls_max_iterations(o.mls.max_iterations);
  p->set_mls_warm_start(o.mls.warm_start);
  switch (o.mls.far_queries) {
    case FarQueryPolicy::kSeedUntilConverged:
      p->set_mls_far_queries(v1::FAR_QUERY_POLICY_SEED_UNTIL_CONVERGED);
      break;
    case FarQueryPolicy::kSeed:
      p->set_mls_far_queries(v1::FAR_QUERY_POLICY_SEED);
      break;
    case FarQueryPolicy::kDrop:
      p->set_mls_far_queries(v1::FAR_QUERY_POLICY_DROP);
      break;
  }
  p->set_min_normal_dot(o.filter.min_normal_dot);
  p->set_min_curvature_ratio(o.filter.min_curvature_ratio);
  p->set_max_distance_d(o.filter.max_distance_d);
  p->set_sicp_p(o.sicp.p);
  p->set_sicp_max_outer(o.sicp.max_outer);
  p->set_sicp_length_unit_d(o.sicp_length_unit_d);
  p->set_gicp_covariance_neighbors(o.gicp.covariance_neighbors);
  p->set_gicp_epsilon(o.gicp.epsilon);
  p->set_gicp_max_distance_d(o.gicp.max_distance_d);
  p->set_fgr_feature_radius_d(o.fgr.feature_radius_d);
  p->set_fgr_samples(o.fgr.samples);
  p->set_sicp_metric(o.sicp.metric == SicpMetric::kPointToPoint ? v1::SICP_METRIC_POINT_TO_POINT
                                                                : v1::SICP_METRIC_POINT_TO_PLANE);
}

// ------------------------------------------------------------------------------------ results

v1::Termination TerminationToProto(Termination t) {
  switch (t) {
    case Termination::kConverged:
      return v1::TERMINATION_CONVERGED;
    case Termination::kMaxIterations:
      return v1::TERMINATION_MAX_ITERATIONS;
    case Termination::kCancelled:
      return v1::TERMINATION_CANCELLED;
    case Termination::kTooFewCorrespondences:
      return v1::TERMINATION_TOO_FEW_CORRESPONDENCES;
  }
  return v1::TERMINATION_UNSPECIFIED;
}

Termination TerminationFromProto(v1::Termination t) {
  switch (t) {
    case v1::TERMINATION_CONVERGED:
      return Termination::kConverged;
    case v1::TERMINATION_CANCELLED:
      return Termination::kCancelled;
    case v1::TERMINATION_TOO_FEW_CORRESPONDENCES:
      return Termination::kTooFewCorrespondences;
    default:
      return Termination::kMaxIterations;
  }
}

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
}

IterationReport FromProto(const v1::Progress& p) {
  IterationReport r;
  r.iteration = p.iteration();
  if (p.transform().row_major_size() == 16) {
    for (int i = 0; i < 16; ++i) r.transform(i / 4, i % 4) = p.transform().row_major(i);
  }
  r.rmse = p.rmse();
  r.rmse_d = p.rmse_d();
  r.counts.matched = p.counts().matched();
  r.counts.rejected_normal = p.counts().rejected_normal();
  r.counts.rejected_curvature = p.counts().rejected_curvature();
  r.counts.rejected_distance = p.counts().rejected_distance();
  r.counts.invalid = p.counts().invalid();
  r.admm_iterations = p.admm_iterations();
  r.elapsed_seconds = p.elapsed_seconds();
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
}

RegistrationResult FromProto(const v1::Result& p) {
  RegistrationResult r;
  if (p.transform().row_major_size() == 16) {
    for (int i = 0; i < 16; ++i) r.transform(i / 4, i % 4) = p.transform().row_major(i);
  }
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

// ------------------------------------------------------------------------------------ requests

void BuildRegisterHeader(const std::string& target_id, const PointCloud& source,
                         v1::ScalarType scalar_type, const RegistrationOptions& options,
                         const Matrix4& initial, const std::optional<Matrix4>& ground_truth,
                         v1::RegisterHeader* header, std::string* payload) {
  header->set_target_id(target_id);
  v1::Method method;
  OptionsToProto(options, &method, header->mutable_parameters());
  header->set_method(method);
  ToProto(initial, header->mutable_initial_transform());
  if (ground_truth) ToProto(*ground_truth, header->mutable_ground_truth());
  EncodeCloud(source, scalar_type, header->mutable_source(), payload);
}

bool WriteChunks(std::string_view payload, std::size_t chunk_bytes,
                 const std::function<bool(const v1::CloudChunk&)>& write) {
  v1::CloudChunk chunk;
  for (std::size_t offset = 0; offset < payload.size(); offset += chunk_bytes) {
    chunk.set_offset(offset);
    chunk.set_data(std::string(payload.substr(offset, chunk_bytes)));
    if (!write(chunk)) return false;
  }
  return true;
}

}  // namespace mlsreg::wire
