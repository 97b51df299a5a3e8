// The cloud codec: a CloudHeader plus packed little-endian records <-> PointCloud, the
// assembler that collects a payload from CloudChunk messages, and the one chunk splitter.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "mlsreg/core/point_cloud.h"
#include "mlsreg/v1/mlsreg.pb.h"

namespace mlsreg::wire {

// Bytes of one point record (3 or 6 scalars of 4 or 8 bytes); 0 for an unspecified scalar type.
std::size_t RecordBytes(const v1::CloudHeader& header);

// Checks a header before any data is accepted: scalar type set, 1 <= point_count <= max_points,
// finite viewpoint, intrinsics within the depth-grid limits. `field` prefixes messages (e.g.
// "header.cloud"). Returns the payload size.
absl::StatusOr<std::uint64_t> CheckCloudHeader(const v1::CloudHeader& header,
                                               std::uint64_t max_points, std::string_view field);

// What the cloud will cost as a built Target (Target::EstimateBytes), from its header alone.
std::uint64_t EstimatedTargetBytes(const v1::CloudHeader& header);

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

// Calls `write(chunk)` for consecutive chunks of `payload` of at most `chunk_bytes` (offsets
// set), until it returns false or the payload is sent; returns whether all were written.
bool WriteChunks(std::string_view payload, std::size_t chunk_bytes,
                 const std::function<bool(const v1::CloudChunk&)>& write);

}  // namespace mlsreg::wire
