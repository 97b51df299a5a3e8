// Writes the seed corpora of the fuzz targets from the test data: the first points of a bundled
// Stanford bunny scan in every format the readers take, small meshes, a sidecar, and the wire
// messages an upload and a registration send. Usage: mlsreg_fuzz_seeds SOURCE_DIR OUT_DIR
// (OUT_DIR/<target>/seed-N files).
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "fuzz_targets.h"
#include "mlsreg/geometry/depth_grid.h"
#include "mlsreg/io/intrinsics_sidecar.h"
#include "mlsreg/io/io.h"
#include "mlsreg/registration/registration.h"
#include "mlsreg/v1/mlsreg.pb.h"
#include "mlsreg/wire/convert.h"

namespace fs = std::filesystem;
using namespace mlsreg;

namespace {

void Write(const fs::path& dir, const std::vector<std::string>& seeds) {
  fs::create_directories(dir);
  for (std::size_t i = 0; i < seeds.size(); ++i) {
    std::ofstream(dir / ("seed-" + std::to_string(i)), std::ios::binary) << seeds[i];
  }
}

PointCloud Head(const PointCloud& cloud, std::size_t n, bool normals) {
  PointCloud out;
  out.points.assign(cloud.points.begin(), cloud.points.begin() + std::min(n, cloud.size()));
  if (normals) {
    for (std::size_t i = 0; i < out.points.size(); ++i) out.normals.push_back(Vec3(0, 0, 1));
  }
  return out;
}

std::string UploadFrames(const PointCloud& cloud, v1::ScalarType type, std::size_t chunk) {
  v1::CreateTargetRequest header;
  header.mutable_header()->set_target_id("seed");
  std::string payload;
  wire::EncodeCloud(cloud, type, header.mutable_header()->mutable_cloud(), &payload);
  std::string frames;
  fuzz::AppendFrame(header.SerializeAsString(), &frames);
  for (std::size_t offset = 0; offset < payload.size(); offset += chunk) {
    v1::CreateTargetRequest message;
    message.mutable_chunk()->set_offset(offset);
    message.mutable_chunk()->set_data(payload.substr(offset, chunk));
    fuzz::AppendFrame(message.SerializeAsString(), &frames);
  }
  return frames;
}

// A binary PCD as PCL writes it compressed (DATA binary_compressed: the fields one after the
// other, LZF-compressed), here with literal LZF runs only; `sizes` are the fields' bytes.
std::string CompressedPcd(const PointCloud& cloud, const std::vector<std::size_t>& sizes) {
  const std::string binary = SerializePcd(cloud, PcdEncoding::kBinary);
  const std::size_t data = binary.find("DATA binary\n") + 12;
  std::size_t record = 0;
  for (std::size_t size : sizes) record += size;
  std::string fields;
  for (std::size_t f = 0, offset = 0; f < sizes.size(); offset += sizes[f++]) {
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      fields += binary.substr(data + i * record + offset, sizes[f]);
    }
  }
  std::string lzf;
  for (std::size_t at = 0; at < fields.size(); at += 32) {
    const std::size_t n = std::min<std::size_t>(32, fields.size() - at);
    lzf += static_cast<char>(n - 1);
    lzf += fields.substr(at, n);
  }
  std::string out = binary.substr(0, data - 7) + "binary_compressed\n";
  for (std::uint32_t word :
       {static_cast<std::uint32_t>(lzf.size()), static_cast<std::uint32_t>(fields.size())}) {
    for (int k = 0; k < 4; ++k) out += static_cast<char>((word >> (8 * k)) & 0xff);
  }
  return out + lzf;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s SOURCE_DIR OUT_DIR\n", argv[0]);
    return 2;
  }
  const fs::path out = argv[2];
  auto scan = ReadPointCloud(std::string(argv[1]) + "/data/bunny/bun000.ply");
  if (!scan.ok()) {
    std::fprintf(stderr, "%s\n", std::string(scan.status().message()).c_str());
    return 1;
  }
  const PointCloud plain = Head(*scan, 40, false), with_normals = Head(*scan, 20, true);
  PointCloud coloured = Head(*scan, 20, false);
  for (std::size_t i = 0; i < coloured.size(); ++i) {
    coloured.colors.push_back({static_cast<std::uint8_t>(10 * i), 128, 255});
  }
  std::vector<std::string> ply = {SerializePly(coloured, PlyEncoding::kAscii)},
                           pcd = {SerializePcd(coloured, PcdEncoding::kAscii),
                                  CompressedPcd(plain, {8, 8, 8}),
                                  CompressedPcd(coloured, {8, 8, 8, 4})},
                           xyz = {SerializeXyz(coloured), "x y z intensity\n1 2 3 0.5\n4 5 6 1\n",
                                  "1 2 3 255 0 10\n4 5 6 0 128 7\n"},
                           npy;
  for (const PointCloud* c : {&plain, &with_normals}) {
    for (PlyEncoding e :
         {PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian, PlyEncoding::kBinaryBigEndian}) {
      ply.push_back(SerializePly(*c, e));
    }
    for (PcdEncoding e : {PcdEncoding::kAscii, PcdEncoding::kBinary})
      pcd.push_back(SerializePcd(*c, e));
    xyz.push_back(SerializeXyz(*c));
    npy.push_back(SerializeNpy(*c));
  }
  Write(out / "ply_reader", ply);
  Write(out / "pcd_reader", pcd);
  Write(out / "xyz_reader", xyz);
  Write(out / "npy_reader", npy);
  Write(out / "off_reader",
        {"OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 1 3\n3 0 2 3\n3 1 2 3\n",
         "OFF 4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n"});
  Write(out / "obj_reader",
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1/1/1 3/2/2 4/3/3\n",
         "# quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf -4//1 -3//1 -2//1 -1//1\n"});
  Write(out / "intrinsics_reader",
        {FormatIntrinsics(PinholeIntrinsics{320, 240, 300, 300, 160, 120}),
         "640 480 525 525 319.5 239.5\n"});
  Write(out / "wire_cloud", {UploadFrames(plain, v1::SCALAR_TYPE_FLOAT64, 256),
                             UploadFrames(with_normals, v1::SCALAR_TYPE_FLOAT32, 100)});
  std::vector<std::string> headers;
  for (Method method : AllMethods()) {
    RegistrationOptions options;
    options.method = method;
    v1::RegisterHeader header;
    header.set_target_id("seed");
    v1::Method wire_method;
    wire::OptionsToProto(options, &wire_method, header.mutable_parameters());
    header.set_method(wire_method);
    wire::ToProto(Matrix4(Matrix4::Identity()), header.mutable_initial_transform());
    headers.push_back(header.SerializeAsString());
  }
  Write(out / "wire_parameters", headers);
  return 0;
}
