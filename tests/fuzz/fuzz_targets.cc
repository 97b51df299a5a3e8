#include "fuzz_targets.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "google/protobuf/stubs/logging.h"
#include "mlsreg/core/triangle_mesh.h"
#include "mlsreg/geometry/depth_grid.h"
#include "mlsreg/io/intrinsics_sidecar.h"
#include "mlsreg/io/io.h"
#include "mlsreg/io/mesh_io.h"
#include "mlsreg/registration/registration.h"
#include "mlsreg/v1/mlsreg.pb.h"
#include "mlsreg/wire/convert.h"

namespace mlsreg::fuzz {
namespace {

// A property of a parser's output does not hold: report it and crash, so libFuzzer keeps the
// input.
[[noreturn]] void Violated(const char* what, const std::string& detail = "") {
  std::fprintf(stderr, "fuzz property violated: %s %s\n", what, detail.c_str());
  std::abort();
}

// The same coordinates and normals, bit for bit, and the same colours unless `colors` is false
// (a format that does not hold them).
bool SameNumbers(const PointCloud& a, const PointCloud& b, bool colors) {
  if (a.points.size() != b.points.size() || a.normals.size() != b.normals.size()) return false;
  if (colors && a.colors != b.colors) return false;
  for (std::size_t i = 0; i < a.points.size(); ++i) {
    if (std::memcmp(a.points[i].data(), b.points[i].data(), sizeof(Vec3)) != 0) return false;
  }
  for (std::size_t i = 0; i < a.normals.size(); ++i) {
    if (std::memcmp(a.normals[i].data(), b.normals[i].data(), sizeof(Vec3)) != 0) return false;
  }
  return true;
}

template <class Parse, class Serialize>
void CloudReader(std::string_view bytes, Parse parse, Serialize serialize, bool colors = true) {
  absl::StatusOr<PointCloud> cloud = parse(bytes);
  if (!cloud.ok()) {
    if (cloud.status().message().empty()) Violated("an error without a message");
    return;
  }
  if (absl::Status s = ValidatePointCloud(*cloud); !s.ok()) {
    Violated("parsed cloud is invalid:", std::string(s.message()));
  }
  absl::StatusOr<PointCloud> again = parse(serialize(*cloud));
  if (!again.ok())
    Violated("written cloud does not read back:", std::string(again.status().message()));
  if (!SameNumbers(*cloud, *again, colors)) Violated("round trip changed the numbers");
}

void MeshReader(std::string_view bytes, absl::StatusOr<TriangleMesh> (*parse)(std::string_view)) {
  absl::StatusOr<TriangleMesh> mesh = parse(bytes);
  if (!mesh.ok()) {
    if (mesh.status().message().empty()) Violated("an error without a message");
    return;
  }
  if (absl::Status s = ValidateTriangleMesh(*mesh); !s.ok()) {
    Violated("parsed mesh is invalid:", std::string(s.message()));
  }
}

}  // namespace

void PlyReader(std::string_view bytes) {
  CloudReader(bytes, ParsePly, [](const PointCloud& c) {
    return SerializePly(c, PlyEncoding::kBinaryLittleEndian);
  });
}
void PcdReader(std::string_view bytes) {
  CloudReader(bytes, ParsePcd,
              [](const PointCloud& c) { return SerializePcd(c, PcdEncoding::kBinary); });
}
void XyzReader(std::string_view bytes) { CloudReader(bytes, ParseXyz, SerializeXyz); }
void NpyReader(std::string_view bytes) {
  CloudReader(bytes, ParseNpy, SerializeNpy, /*colors=*/false);  // NPY files hold no colours
}
void OffReader(std::string_view bytes) { MeshReader(bytes, ParseOff); }
void ObjReader(std::string_view bytes) { MeshReader(bytes, ParseObj); }

void IntrinsicsReader(std::string_view bytes) {
  absl::StatusOr<PinholeIntrinsics> k = ParseIntrinsics(bytes, "sidecar");
  if (!k.ok()) return;
  if (absl::Status s = ValidateIntrinsics(*k, "sidecar"); !s.ok()) {
    Violated("parsed intrinsics are invalid:", std::string(s.message()));
  }
}

void Initialize() {
  google::protobuf::SetLogHandler(
      [](google::protobuf::LogLevel, const char*, int, const std::string&) {});
}

void AppendFrame(std::string_view message, std::string* out) {
  const auto n = static_cast<std::uint32_t>(message.size());
  for (int i = 0; i < 4; ++i) out->push_back(static_cast<char>((n >> (8 * i)) & 0xff));
  out->append(message);
}

void WireCloud(std::string_view bytes) {
  // Small limits, so that the fuzzer explores the logic rather than allocating.
  constexpr std::uint64_t kMaxPoints = 1 << 14;
  constexpr std::size_t kMaxChunkBytes = 1 << 12;
  auto next = [&bytes](v1::CreateTargetRequest* message) {
    if (bytes.size() < 4) return false;
    std::uint32_t n = 0;
    for (int i = 0; i < 4; ++i)
      n |= static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i])) << (8 * i);
    bytes.remove_prefix(4);
    if (n > bytes.size()) return false;
    const bool parsed = message->ParseFromArray(bytes.data(), static_cast<int>(n));
    bytes.remove_prefix(n);
    return parsed;
  };
  v1::CreateTargetRequest message;
  if (!next(&message) || !message.has_header()) return;
  const v1::CloudHeader header = message.header().cloud();
  absl::StatusOr<std::uint64_t> expected =
      wire::CheckCloudHeader(header, kMaxPoints, "header.cloud");
  if (!expected.ok()) return;
  if (*expected != header.point_count() * wire::RecordBytes(header)) Violated("declared size");
  wire::PayloadAssembler payload(*expected, kMaxChunkBytes, "chunk");
  while (!payload.complete()) {
    if (!next(&message) || !message.has_chunk()) return;
    if (!payload.Append(message.chunk()).ok()) return;
    if (payload.received() > *expected) Violated("assembled more than declared");
  }
  absl::StatusOr<PointCloud> cloud = wire::DecodeCloud(header, payload.payload(), "cloud");
  if (!cloud.ok()) return;
  if (cloud->size() != header.point_count()) Violated("decoded point count");
  if (absl::Status s = ValidatePointCloud(*cloud); !s.ok()) {
    Violated("decoded cloud is invalid:", std::string(s.message()));
  }
}

void WireParameters(std::string_view bytes) {
  v1::RegisterHeader header;
  if (!header.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) return;
  absl::StatusOr<RegistrationOptions> options =
      wire::OptionsFromProto(header.method(), header.parameters());
  if (options.ok()) {
    if (absl::Status s = ValidateOptions(*options); !s.ok()) {
      Violated("accepted parameters fail ValidateOptions:", std::string(s.message()));
    }
    v1::Method method;
    v1::RegistrationParameters parameters;
    wire::OptionsToProto(*options, &method, &parameters);
    absl::StatusOr<RegistrationOptions> again = wire::OptionsFromProto(method, parameters);
    if (!again.ok())
      Violated("parameters do not convert back:", std::string(again.status().message()));
    v1::Method method2;
    v1::RegistrationParameters parameters2;
    wire::OptionsToProto(*again, &method2, &parameters2);
    if (method != method2 || parameters.SerializeAsString() != parameters2.SerializeAsString()) {
      Violated("parameters changed in a round trip");
    }
  }
  if (header.has_initial_transform()) {
    (void)wire::FromProto(header.initial_transform(), "header.initial_transform");
  }
}

}  // namespace mlsreg::fuzz
