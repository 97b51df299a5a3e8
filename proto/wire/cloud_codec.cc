#include "mlsreg/wire/cloud_codec.h"

#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

#include "absl/strings/str_cat.h"
#include "mlsreg/geometry/depth_grid.h"
#include "mlsreg/geometry/target.h"

namespace mlsreg::wire {

std::size_t RecordBytes(const v1::CloudHeader& header) {
  std::size_t scalar = 0;
  if (header.scalar_type() == v1::SCALAR_TYPE_FLOAT32) scalar = 4;
  if (header.scalar_type() == v1::SCALAR_TYPE_FLOAT64) scalar = 8;
  return scalar * (header.has_normals() ? 6 : 3);
}

std::uint64_t EstimatedTargetBytes(const v1::CloudHeader& cloud) {
  std::optional<PinholeIntrinsics> intrinsics;
  if (cloud.has_intrinsics()) {
    intrinsics = PinholeIntrinsics{cloud.intrinsics().width(), cloud.intrinsics().height()};
  }
  return Target::EstimateBytes(cloud.point_count(), cloud.has_normals(), intrinsics);
}

absl::StatusOr<std::uint64_t> CheckCloudHeader(const v1::CloudHeader& header,
                                               std::uint64_t max_points, std::string_view field) {
  const std::string f(field);
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
  const std::string f(field);
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
