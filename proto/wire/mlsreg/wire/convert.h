// Conversions between the mlsreg.v1 wire types and the library's domain types, with the
// validation every server entry point needs. Errors are absl::InvalidArgumentError whose message
// starts with the offending field path (e.g. "source.points[12]: non-finite coordinate").
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "grpcpp/support/status.h"
#include "mlsreg/evaluation/metrics.h"
#include "mlsreg/registration/registration.h"
#include "mlsreg/v1/mlsreg.pb.h"

namespace mlsreg::wire {

// ---- status
grpc::Status ToGrpcStatus(const absl::Status& status);
absl::Status ToAbslStatus(const grpc::Status& status);

// ---- clouds
// Bytes of one point record (3 or 6 scalars of 4 or 8 bytes); 0 for an unspecified scalar type.
std::size_t RecordBytes(const v1::CloudHeader& header);

// Checks a header before any data is accepted: scalar type set, 1 <= point_count <= max_points,
// finite viewpoint. `field` prefixes messages (e.g. "header.cloud"). Returns the payload size.
absl::StatusOr<std::uint64_t> CheckCloudHeader(const v1::CloudHeader& header,
                                               std::uint64_t max_points, std::string_view field);

// Decodes a complete payload (size must be point_count * RecordBytes). Rejects NaN/Inf
// coordinates and zero or non-finite normals naming "<field>.points[i]".
absl::StatusOr<PointCloud> DecodeCloud(const v1::CloudHeader& header, std::string_view payload,
                                       std::string_view field);

// Packs a cloud (normals included when present) and fills its header.
void EncodeCloud(const PointCloud& cloud, v1::ScalarType scalar_type, v1::CloudHeader* header,
                 std::string* payload);

// Collects exactly the declared payload from CloudChunk messages: in order (offset == bytes so
// far), each at most `max_chunk_bytes` of data, never beyond the total. The buffer grows as data
// arrives (never past the total), so a header that declares a huge cloud costs nothing until its
// data comes.
class PayloadAssembler {
 public:
  PayloadAssembler(std::uint64_t expected_bytes, std::size_t max_chunk_bytes, std::string field);
  // INVALID_ARGUMENT naming "<field>.data" or "<field>.offset".
  absl::Status Append(const v1::CloudChunk& chunk);
  // The stream ended before the payload was complete: INVALID_ARGUMENT naming "<field>".
  absl::Status EndedEarly() const;
  bool complete() const { return payload_.size() == expected_; }
  std::uint64_t received() const { return payload_.size(); }
  std::string_view payload() const { return payload_; }
  std::string Release() { return std::move(payload_); }

 private:
  std::uint64_t expected_;
  std::size_t max_chunk_bytes_;
  std::string field_;
  std::string payload_;
};

// ---- transforms
void ToProto(const Matrix4& m, v1::Transform* out);
// 16 finite numbers forming a rigid transform; `field` names it in errors.
absl::StatusOr<Matrix4> FromProto(const v1::Transform& t, std::string_view field);

// ---- registration options
std::string_view MethodName(v1::Method method);  // "mls-sicp", ...; "" for unknown values
absl::StatusOr<Method> MethodFromProto(v1::Method method);  // UNSPECIFIED -> kMlsSicp
v1::Method MethodToProto(Method method);
// Library defaults overridden by every set field; validated (field names "parameters.<name>").
absl::StatusOr<RegistrationOptions> OptionsFromProto(v1::Method method,
                                                     const v1::RegistrationParameters& p);
// Every field set explicitly (so a request is reproducible whatever the server's defaults).
void OptionsToProto(const RegistrationOptions& options, v1::Method* method,
                    v1::RegistrationParameters* p);

// ---- results
void ToProto(const IterationReport& report, v1::Progress* out);
void ToProto(const RegistrationResult& result, v1::Result* out);
IterationReport FromProto(const v1::Progress& progress);
// The library result as far as the wire carries it (the trace is left empty).
RegistrationResult FromProto(const v1::Result& result);
v1::Termination TerminationToProto(Termination t);
Termination TerminationFromProto(v1::Termination t);
void ToProto(const PoseError& error, v1::GroundTruthError* out);
PoseError FromProto(const v1::GroundTruthError& error);

// ---- requests
// The header of a Register call: target, method and every parameter, the initial transform,
// the ground truth when given, and the source's header; its packed data goes to `payload`
// (inline or in chunks: the caller decides).
void BuildRegisterHeader(const std::string& target_id, const PointCloud& source,
                         v1::ScalarType scalar_type, const RegistrationOptions& options,
                         const Matrix4& initial, const std::optional<Matrix4>& ground_truth,
                         v1::RegisterHeader* header, std::string* payload);
// Calls `write(chunk)` for consecutive chunks of `payload` of at most `chunk_bytes` (offsets
// set), until it returns false or the payload is sent; returns whether all were written.
bool WriteChunks(std::string_view payload, std::size_t chunk_bytes,
                 const std::function<bool(const v1::CloudChunk&)>& write);

}  // namespace mlsreg::wire
