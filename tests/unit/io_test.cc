// Tests of mlsreg/io.h: round trips, the real bunny scan, hand-built PLY/PCD/XYZ files, every
// kind of malformed input, file-level errors, and a seeded mutation test.

#include "mlsreg/io/io.h"

#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <limits>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_replace.h"
#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "mlsreg/core/point_cloud.h"

namespace mlsreg {
namespace {

using ::testing::HasSubstr;
using ::testing::StartsWith;

// ---------------------------------------------------------------------------------------------
// Helpers.

// A cloud whose coordinates exercise every corner of double formatting: signed zero, subnormals,
// huge and tiny exponents, 17-digit mantissas, then random finite bit patterns. Normals are unit.
PointCloud MakeCloud(int size, bool with_normals, std::uint64_t seed = 7) {
  std::mt19937_64 random(seed);
  const auto random_finite = [&random] {
    while (true) {
      const double value = std::bit_cast<double>(random());
      if (std::isfinite(value)) return value;
    }
  };
  PointCloud cloud;
  const Vec3 fixed[] = {{-0.0, 5e-324, 1e300},
                        {0.1, -1e-300, 123456789.123456789},
                        {1.0 / 3.0, -2.0 / 3.0, std::numeric_limits<double>::max()}};
  for (int i = 0; i < size; ++i) {
    if (i < 3) {
      cloud.points.push_back(fixed[i]);
    } else {
      cloud.points.emplace_back(random_finite(), random_finite(), std::ldexp(i * 0.37, -i));
    }
  }
  std::normal_distribution<double> gaussian;
  for (int i = 0; with_normals && i < size; ++i) {
    cloud.normals.push_back(
        Vec3(gaussian(random), gaussian(random), gaussian(random) + 0.1).normalized());
  }
  return cloud;
}

// Expects every coordinate and normal component of `actual` to have the same bits as `expected`.
void ExpectBitExact(const PointCloud& actual, const PointCloud& expected) {
  ASSERT_EQ(actual.size(), expected.size());
  ASSERT_EQ(actual.normals.size(), expected.normals.size());
  EXPECT_EQ(actual.colors, expected.colors);
  for (std::size_t i = 0; i < expected.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      ASSERT_EQ(std::bit_cast<std::uint64_t>(actual.points[i][k]),
                std::bit_cast<std::uint64_t>(expected.points[i][k]))
          << "point " << i << " component " << k << ": " << actual.points[i][k] << " vs "
          << expected.points[i][k];
      if (expected.has_normals()) {
        ASSERT_EQ(std::bit_cast<std::uint64_t>(actual.normals[i][k]),
                  std::bit_cast<std::uint64_t>(expected.normals[i][k]))
            << "normal " << i << " component " << k;
      }
    }
  }
}

// Expects `result` to have failed with `code` and a message containing every one of `parts`.
void ExpectError(const absl::StatusOr<PointCloud>& result, absl::StatusCode code,
                 std::initializer_list<std::string_view> parts) {
  ASSERT_FALSE(result.ok()) << "parsed " << result->size() << " points";
  EXPECT_EQ(result.status().code(), code) << result.status();
  const std::string message(result.status().message());
  for (std::string_view part : parts) EXPECT_THAT(message, HasSubstr(std::string(part)));
}

const char* PlyFormatName(PlyEncoding encoding) {
  switch (encoding) {
    case PlyEncoding::kAscii:
      return "ascii";
    case PlyEncoding::kBinaryLittleEndian:
      return "binary_little_endian";
    case PlyEncoding::kBinaryBigEndian:
      return "binary_big_endian";
  }
  return "";
}

// Appends `value` stored as T: its text and a space in ASCII, else its bytes in the encoding's
// byte order.
template <typename T>
void Put(std::string* out, PlyEncoding encoding, T value) {
  if (encoding == PlyEncoding::kAscii) {
    absl::StrAppend(out, +value, " ");  // '+' prints char types as numbers.
    return;
  }
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  const std::endian order =
      encoding == PlyEncoding::kBinaryBigEndian ? std::endian::big : std::endian::little;
  if (order != std::endian::native) std::reverse(bytes, bytes + sizeof(T));
  out->append(bytes, sizeof(T));
}

// Ends an element instance: in ASCII the trailing space becomes a newline.
void EndInstance(std::string* out, PlyEncoding encoding) {
  if (encoding == PlyEncoding::kAscii) out->back() = '\n';
}

// A minimal ASCII PLY with `count` declared vertices and the given data lines (line 8 onward).
std::string AsciiPly(const std::string& data_lines, int count = 3) {
  return absl::StrCat("ply\nformat ascii 1.0\nelement vertex ", count,
                      "\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
                      data_lines);
}
constexpr char kThreeVertices[] = "0 0 0\n1 0 0\n0 1 0\n";  // lines 8, 9, 10

// A minimal ASCII PCD with `points` declared and the given data lines (line 12 onward).
std::string AsciiPcd(const std::string& data_lines, int points = 3) {
  return absl::StrCat(
      "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH ", points,
      "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS ", points, "\nDATA ascii\n", data_lines);
}

// ---------------------------------------------------------------------------------------------
// Round trips.

struct RoundTripCase {
  std::string name;
  std::function<std::string(const PointCloud&)> serialize;
  std::function<absl::StatusOr<PointCloud>(std::string_view)> parse;
};

std::vector<RoundTripCase> RoundTripCases() {
  return {
      {"PlyAscii", [](const PointCloud& c) { return SerializePly(c, PlyEncoding::kAscii); },
       ParsePly},
      {"PlyBinaryLittleEndian",
       [](const PointCloud& c) { return SerializePly(c, PlyEncoding::kBinaryLittleEndian); },
       ParsePly},
      {"PlyBinaryBigEndian",
       [](const PointCloud& c) { return SerializePly(c, PlyEncoding::kBinaryBigEndian); },
       ParsePly},
      {"PcdAscii", [](const PointCloud& c) { return SerializePcd(c, PcdEncoding::kAscii); },
       ParsePcd},
      {"PcdBinary", [](const PointCloud& c) { return SerializePcd(c, PcdEncoding::kBinary); },
       ParsePcd},
      {"Xyz", SerializeXyz, ParseXyz},
  };
}

class RoundTripTest : public ::testing::TestWithParam<std::tuple<RoundTripCase, bool>> {};

TEST_P(RoundTripTest, IsBitExact) {
  const auto& [format, with_normals] = GetParam();
  const PointCloud cloud = MakeCloud(200, with_normals);
  const absl::StatusOr<PointCloud> parsed = format.parse(format.serialize(cloud));
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  ExpectBitExact(*parsed, cloud);
  EXPECT_TRUE(ValidatePointCloud(*parsed, 1).ok());
}

INSTANTIATE_TEST_SUITE_P(AllEncodings, RoundTripTest,
                         ::testing::Combine(::testing::ValuesIn(RoundTripCases()),
                                            ::testing::Bool()),
                         [](const auto& info) {
                           return std::get<0>(info.param).name +
                                  (std::get<1>(info.param) ? "WithNormals" : "WithoutNormals");
                         });

TEST(RoundTrip, PcdKeepsTheViewpointBitForBit) {
  PointCloud cloud = MakeCloud(5, true);
  cloud.viewpoint = Vec3(1.0 / 3.0, -2.5e-7, 1e10);
  for (PcdEncoding encoding : {PcdEncoding::kAscii, PcdEncoding::kBinary}) {
    const absl::StatusOr<PointCloud> parsed = ParsePcd(SerializePcd(cloud, encoding));
    ASSERT_TRUE(parsed.ok()) << parsed.status();
    ASSERT_TRUE(parsed->viewpoint.has_value());
    EXPECT_EQ(*parsed->viewpoint, *cloud.viewpoint);
  }
}

TEST(RoundTrip, PcdWithoutViewpointReadsBackTheDefaultOrigin) {
  const absl::StatusOr<PointCloud> parsed = ParsePcd(SerializePcd(MakeCloud(4, false), {}));
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  ASSERT_TRUE(parsed->viewpoint.has_value());
  EXPECT_EQ(*parsed->viewpoint, Vec3::Zero());
}

TEST(RoundTrip, PlyAndXyzHaveNoViewpoint) {
  PointCloud cloud = MakeCloud(4, false);
  cloud.viewpoint = Vec3(1, 2, 3);
  EXPECT_FALSE(ParsePly(SerializePly(cloud, PlyEncoding::kAscii))->viewpoint.has_value());
  EXPECT_FALSE(ParseXyz(SerializeXyz(cloud))->viewpoint.has_value());
}

TEST(Serialize, WritesTheDocumentedHeaders) {
  const PointCloud cloud = MakeCloud(2, true);
  EXPECT_THAT(SerializePly(cloud, PlyEncoding::kBinaryBigEndian),
              StartsWith("ply\nformat binary_big_endian 1.0\n"));
  EXPECT_THAT(SerializePly(cloud, PlyEncoding::kAscii),
              HasSubstr("element vertex 2\nproperty double x\nproperty double y\nproperty double "
                        "z\nproperty double nx\nproperty double ny\nproperty double nz\n"
                        "end_header\n"));
  EXPECT_THAT(SerializePcd(cloud, PcdEncoding::kAscii),
              HasSubstr("VERSION 0.7\nFIELDS x y z normal_x normal_y normal_z\nSIZE 8 8 8 8 8 8\n"
                        "TYPE F F F F F F\nCOUNT 1 1 1 1 1 1\nWIDTH 2\nHEIGHT 1\n"
                        "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA ascii\n"));
  PointCloud simple;
  simple.points = {Vec3(0.1, -2, 3e-5)};
  EXPECT_EQ(SerializeXyz(simple), "0.10000000000000001 -2 3.0000000000000001e-05\n");
  simple.colors = {Rgb{1, 2, 250}};
  EXPECT_EQ(SerializeXyz(simple),
            "x y z r g b\n0.10000000000000001 -2 3.0000000000000001e-05 1 2 250\n");
  EXPECT_THAT(SerializeXyz(cloud), StartsWith("x y z nx ny nz\n"));
  simple.normals = {Vec3(0, 0, 1)};
  EXPECT_THAT(SerializePly(simple, PlyEncoding::kAscii),
              HasSubstr("property double nz\nproperty uchar red\nproperty uchar green\n"
                        "property uchar blue\nend_header\n"));
  EXPECT_THAT(SerializePcd(simple, PcdEncoding::kAscii),
              HasSubstr("FIELDS x y z normal_x normal_y normal_z rgb\nSIZE 8 8 8 8 8 8 4\n"));
}

// Colours survive every format that holds them, bit for bit beside the coordinates; NPY holds
// none.
TEST(RoundTrip, ColoursInEveryFormat) {
  for (bool with_normals : {false, true}) {
    PointCloud cloud = MakeCloud(50, with_normals);
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      cloud.colors.push_back({static_cast<std::uint8_t>(i), static_cast<std::uint8_t>(255 - i),
                              static_cast<std::uint8_t>(i * 7)});
    }
    for (const RoundTripCase& format : RoundTripCases()) {
      SCOPED_TRACE(format.name + (with_normals ? " with normals" : ""));
      const absl::StatusOr<PointCloud> parsed = format.parse(format.serialize(cloud));
      ASSERT_TRUE(parsed.ok()) << parsed.status();
      ExpectBitExact(*parsed, cloud);
    }
    const absl::StatusOr<PointCloud> npy = ParseNpy(SerializeNpy(cloud));
    ASSERT_TRUE(npy.ok()) << npy.status();
    EXPECT_FALSE(npy->has_colors());
    EXPECT_EQ(npy->has_normals(), with_normals);
  }
}

TEST(Ply, ReadsColoursOfAnyTypeAndNamesTheOtherProperties) {
  const absl::StatusOr<CloudFile> file = ParseCloudFile(
      CloudFormat::kPly,
      "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
      "property float z\nproperty ushort red\nproperty float green\nproperty uchar blue\n"
      "property uchar alpha\nproperty float intensity\nend_header\n"
      "0 0 0 65535 1 7 255 0.5\n1 0 0 0 0.5 0 255 0.5\n");
  ASSERT_TRUE(file.ok()) << file.status();
  EXPECT_EQ(file->cloud.colors, (std::vector<Rgb>{{255, 255, 7}, {0, 128, 0}}));
  EXPECT_EQ(file->notes,
            std::vector<std::string>{"PLY: vertex properties read and ignored: alpha, intensity"});
  ExpectError(ParseCloudFile(CloudFormat::kPly, "ply\n", ReadOptions{{"x", "y", "z"}}).status(),
              absl::StatusCode::kInvalidArgument,
              {"PLY or PCD file, whose header names its fields"});
}

TEST(Pcd, ReadsPackedColoursAsFloatOrInteger) {
  for (const char* type : {"F", "U"}) {
    SCOPED_TRACE(type);
    const std::uint32_t packed = (200u << 16) | (100u << 8) | 7u;
    char text[64];
    std::snprintf(text, sizeof(text), "%.9g", static_cast<double>(std::bit_cast<float>(packed)));
    const std::string value = type[0] == 'F' ? std::string(text) : absl::StrCat(packed);
    const absl::StatusOr<CloudFile> file = ParseCloudFile(
        CloudFormat::kPcd,
        absl::StrCat("VERSION 0.7\nFIELDS x y z rgb intensity\nSIZE 4 4 4 4 4\nTYPE F F F ", type,
                     " F\nCOUNT 1 1 1 1 1\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3 ", value,
                     " 0.5\n"));
    ASSERT_TRUE(file.ok()) << file.status();
    EXPECT_EQ(file->cloud.colors, (std::vector<Rgb>{{200, 100, 7}}));
    EXPECT_EQ(file->notes, std::vector<std::string>{"PCD: fields read and ignored: intensity"});
  }
}

// ---------------------------------------------------------------------------------------------
// The real Stanford bunny scan (ASCII PLY with a range_grid list element after the vertices).

TEST(RealData, ReadsTheBunnyScan) {
  // The bundled copy of the Stanford scan (byte-identical to the shared data set).
  const std::string path = MLSREG_SOURCE_DIR "/data/bunny/bun000.ply";
  const absl::StatusOr<PointCloud> cloud = ReadPointCloud(path);
  ASSERT_TRUE(cloud.ok()) << cloud.status();
  ASSERT_EQ(cloud->size(), 40256u);
  EXPECT_FALSE(cloud->has_normals());
  // Line 25 (the first after end_header) and line 40280 (the last vertex line) of the file.
  EXPECT_EQ(cloud->points.front(), Vec3(-0.06325, 0.0359793, 0.0420873));
  EXPECT_EQ(cloud->points.back(), Vec3(-0.018, 0.18794, -0.0197253));
  EXPECT_TRUE(ValidatePointCloud(*cloud, 1).ok());
}

// ---------------------------------------------------------------------------------------------
// Hand-built PLY files.

class PlyEncodingTest : public ::testing::TestWithParam<PlyEncoding> {};

// A face element with a list property before the vertex element, vertex properties of many types
// around x y z (a uchar before, a float and a list after), normals to normalise, and an element
// after the vertices.
TEST_P(PlyEncodingTest, SkipsOtherPropertiesAndElements) {
  const PlyEncoding encoding = GetParam();
  std::string bytes = absl::StrCat("ply\nformat ", PlyFormatName(encoding),
                                   " 1.0\ncomment made by hand\nobj_info nothing\n"
                                   "element face 2\nproperty list uchar int vertex_indices\n"
                                   "element vertex 3\nproperty uchar red\nproperty float x\n"
                                   "property float32 y\nproperty float z\n"
                                   "property float confidence\n"
                                   "property list uint8 float64 weights\n"
                                   "property double nx\nproperty float64 ny\nproperty double nz\n"
                                   "element edge 1\nproperty int vertex1\nproperty int32 vertex2\n"
                                   "end_header\n");
  Put<std::uint8_t>(&bytes, encoding, 3);  // face 0
  for (std::int32_t index : {0, 1, 2}) Put(&bytes, encoding, index);
  EndInstance(&bytes, encoding);
  Put<std::uint8_t>(&bytes, encoding, 0);  // face 1: an empty list
  EndInstance(&bytes, encoding);
  struct Vertex {
    float x, y, z;
    std::vector<double> weights;
    double nx, ny, nz;
  };
  const Vertex vertices[] = {{0.5f, -1.25f, 2.75f, {1.5, 2.5}, 0, 0, 2},
                             {-3.0f, 0.125f, 1e-3f, {}, 3, 0, 4},
                             {7.0f, 8.0f, 9.0f, {-1}, 0, -1, 0}};
  for (const Vertex& v : vertices) {
    Put<std::uint8_t>(&bytes, encoding, 255);
    Put(&bytes, encoding, v.x);
    Put(&bytes, encoding, v.y);
    Put(&bytes, encoding, v.z);
    Put(&bytes, encoding, 0.75f);
    Put(&bytes, encoding, static_cast<std::uint8_t>(v.weights.size()));
    for (double w : v.weights) Put(&bytes, encoding, w);
    Put(&bytes, encoding, v.nx);
    Put(&bytes, encoding, v.ny);
    Put(&bytes, encoding, v.nz);
    EndInstance(&bytes, encoding);
  }
  Put<std::int32_t>(&bytes, encoding, 0);  // edge 0
  Put<std::int32_t>(&bytes, encoding, 1);
  EndInstance(&bytes, encoding);

  const absl::StatusOr<CloudFile> file = ParseCloudFile(CloudFormat::kPly, bytes);
  ASSERT_TRUE(file.ok()) << file.status();
  // A red channel alone is not a colour: read and ignored like the others, and said.
  EXPECT_EQ(file->notes, std::vector<std::string>{
                             "PLY: vertex properties read and ignored: red, confidence, weights"});
  const PointCloud* cloud = &file->cloud;
  EXPECT_FALSE(cloud->has_colors());
  ASSERT_EQ(cloud->size(), 3u);
  ASSERT_TRUE(cloud->has_normals());
  for (int i = 0; i < 3; ++i) {
    const Vertex& v = vertices[i];
    if (encoding == PlyEncoding::kAscii) {  // The text "0.001" is read as the double 0.001.
      EXPECT_EQ(cloud->points[i], Vec3(std::stod(absl::StrCat(v.x)), std::stod(absl::StrCat(v.y)),
                                       std::stod(absl::StrCat(v.z))));
    } else {
      EXPECT_EQ(cloud->points[i], Vec3(v.x, v.y, v.z));
    }
    EXPECT_TRUE(cloud->normals[i].isApprox(Vec3(v.nx, v.ny, v.nz).normalized(), 1e-15))
        << cloud->normals[i].transpose();
  }
}

INSTANTIATE_TEST_SUITE_P(AllPlyEncodings, PlyEncodingTest,
                         ::testing::Values(PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian,
                                           PlyEncoding::kBinaryBigEndian),
                         [](const auto& info) { return std::string(PlyFormatName(info.param)); });

TEST(Ply, ReadsFloat32BigEndianExactly) {
  std::string bytes =
      "ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty float32 x\n"
      "property float32 y\nproperty float32 z\nend_header\n";
  for (float value : {0.1f, -7.3f, 1e-30f}) Put(&bytes, PlyEncoding::kBinaryBigEndian, value);
  const absl::StatusOr<PointCloud> cloud = ParsePly(bytes);
  ASSERT_TRUE(cloud.ok()) << cloud.status();
  EXPECT_EQ(cloud->points[0], Vec3(double{0.1f}, double{-7.3f}, double{1e-30f}));
}

TEST(Ply, ReadsIntegerCoordinates) {
  std::string bytes =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty short x\n"
      "property uint y\nproperty int8 z\nend_header\n";
  Put<std::int16_t>(&bytes, PlyEncoding::kBinaryLittleEndian, -300);
  Put<std::uint32_t>(&bytes, PlyEncoding::kBinaryLittleEndian, 4000000000u);
  Put<std::int8_t>(&bytes, PlyEncoding::kBinaryLittleEndian, -128);
  const absl::StatusOr<PointCloud> cloud = ParsePly(bytes);
  ASSERT_TRUE(cloud.ok()) << cloud.status();
  EXPECT_EQ(cloud->points[0], Vec3(-300, 4000000000.0, -128));
}

TEST(Ply, AcceptsCrLfLinesInTheHeaderOfABinaryFile) {
  const PointCloud cloud = MakeCloud(3, false);
  std::string bytes = SerializePly(cloud, PlyEncoding::kBinaryLittleEndian);
  const std::size_t header_end = bytes.find("end_header\n") + 11;
  bytes =
      absl::StrReplaceAll(bytes.substr(0, header_end), {{"\n", "\r\n"}}) + bytes.substr(header_end);
  const absl::StatusOr<PointCloud> parsed = ParsePly(bytes);
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  ExpectBitExact(*parsed, cloud);
}

TEST(Ply, NormalisesNormals) {
  const absl::StatusOr<PointCloud> cloud = ParsePly(
      "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
      "property float z\nproperty float nx\nproperty float ny\nproperty float nz\nend_header\n"
      "0 0 0 0 0 2\n1 1 1 1e-310 0 0\n2 2 2 0 1.35675105885e-312 1.35675105885e-312\n"
      "3 3 3 1e300 -1e300 0\n");
  ASSERT_TRUE(cloud.ok()) << cloud.status();
  EXPECT_EQ(cloud->normals[0], Vec3(0, 0, 1));
  EXPECT_EQ(cloud->normals[1], Vec3(1, 0, 0));
  EXPECT_NEAR(cloud->normals[2].norm(), 1.0, 1e-15);  // subnormal components
  EXPECT_NEAR(cloud->normals[2].y(), std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(cloud->normals[3].norm(), 1.0, 1e-15);  // squared norm overflows
  EXPECT_NEAR(cloud->normals[3].x(), std::sqrt(0.5), 1e-15);
}

// ---------------------------------------------------------------------------------------------
// Malformed PLY.

constexpr auto kInvalid = absl::StatusCode::kInvalidArgument;

TEST(PlyErrors, TextWhereANumberShouldBe) {
  ExpectError(ParsePly(AsciiPly("0 0 0\n1 0 0\n0 1x 0\n")), kInvalid,
              {"PLY line 10, vertex 2", "property 'y'", "'1x'", "not a number"});
}

TEST(PlyErrors, ExtraValueOnAVertexLine) {
  ExpectError(ParsePly(AsciiPly("0 0 0\n1 0 0 7\n0 1 0\n")), kInvalid,
              {"line 9, vertex 1", "unexpected '7'"});
}

TEST(PlyErrors, MissingValueOnAVertexLine) {
  ExpectError(ParsePly(AsciiPly("0 0 0\n1 0 0\n0 1\n")), kInvalid,
              {"line 10, vertex 2", "ends before property 'z'"});
}

TEST(PlyErrors, AsciiHeaderDeclaresMoreVerticesThanLines) {
  ExpectError(ParsePly(AsciiPly("0.00 0.00 0.00\n1.00 0.00 0.00\n0.00 1.00 0.00\n", 5)), kInvalid,
              {"line 10", "ends after 3 of the 5 vertices"});
  ExpectError(ParsePly(AsciiPly(kThreeVertices, 1000000000)), kInvalid,
              {"line 10", "ends after 3 of the 1000000000 vertices"});
}

TEST(PlyErrors, AsciiDataAfterTheLastElement) {
  ExpectError(ParsePly(AsciiPly(absl::StrCat(kThreeVertices, "\n5 5 5\n"))), kInvalid,
              {"line 12", "unexpected data after the last element"});
  EXPECT_TRUE(ParsePly(AsciiPly(absl::StrCat(kThreeVertices, "\n  \n"))).ok());
}

TEST(PlyErrors, NonFiniteCoordinates) {
  ExpectError(ParsePly(AsciiPly("0 0 0\nnan 0 0\n0 1 0\n")), kInvalid,
              {"line 9, vertex 1", "coordinate x is not finite"});
  ExpectError(ParsePly(AsciiPly("0 0 0\n1 0 0\n0 -inf 0\n")), kInvalid,
              {"line 10, vertex 2", "coordinate y is not finite (-inf)"});
  ExpectError(ParsePly(AsciiPly("0 0 0\n1 0 1e999\n0 1 0\n")), kInvalid,
              {"line 9, vertex 1", "'1e999' is not a number"});

  PointCloud cloud = MakeCloud(3, false);
  cloud.points[1].z() = std::numeric_limits<double>::infinity();
  for (PlyEncoding encoding : {PlyEncoding::kBinaryLittleEndian, PlyEncoding::kBinaryBigEndian}) {
    const std::string bytes = SerializePly(cloud, encoding);
    const std::size_t vertex_1 = bytes.find("end_header\n") + 11 + 24;
    ExpectError(ParsePly(bytes), kInvalid,
                {absl::StrCat("PLY byte offset ", vertex_1, ", vertex 1"),
                 "coordinate z is not finite (inf)"});
  }
}

TEST(PlyErrors, BadNormals) {
  PointCloud cloud = MakeCloud(3, true);
  cloud.normals[1] = Vec3::Zero();
  ExpectError(ParsePly(SerializePly(cloud, PlyEncoding::kAscii)), kInvalid,
              {"line 13, vertex 1", "normal (0, 0, 0) has zero length"});
  cloud.normals[1] = Vec3(0, std::nan(""), 1);
  ExpectError(ParsePly(SerializePly(cloud, PlyEncoding::kBinaryBigEndian)), kInvalid,
              {"byte offset", "vertex 1", "non-finite component"});
}

TEST(PlyErrors, ZeroVertices) {
  ExpectError(ParsePly(AsciiPly("", 0)), kInvalid, {"PLY file contains no points"});
  ExpectError(ParsePly(SerializePly(PointCloud{}, PlyEncoding::kBinaryLittleEndian)), kInvalid,
              {"contains no points"});
}

TEST(PlyErrors, BadHeaders) {
  const auto with_header = [](const std::string& header) {
    return absl::StrCat(header, "end_header\n", kThreeVertices);
  };
  ExpectError(ParsePly(""), kInvalid, {"not a PLY file"});
  ExpectError(ParsePly("plyx\n"), kInvalid, {"not a PLY file"});
  ExpectError(ParsePly("ply\nformat ascii 1.0\nelement vertex 1\n"), kInvalid,
              {"no \"end_header\""});
  ExpectError(ParsePly(with_header("ply\nformat utf8 1.0\nelement vertex 3\nproperty float x\n"
                                   "property float y\nproperty float z\n")),
              kInvalid, {"line 2", "unknown format 'utf8'"});
  ExpectError(ParsePly(with_header("ply\nformat ascii 2.0\n")), kInvalid,
              {"line 2", "version '2.0'"});
  ExpectError(ParsePly(with_header("ply\nelement vertex 3\nproperty float x\nproperty float y\n"
                                   "property float z\n")),
              kInvalid, {"no \"format\""});
  ExpectError(ParsePly(with_header("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                   "property float y\n")),
              kInvalid, {"line 3", "no 'z' property"});
  ExpectError(ParsePly(with_header("ply\nformat ascii 1.0\nelement face 3\n"
                                   "property list uchar int vertex_indices\n")),
              kInvalid, {"no \"vertex\" element"});
  ExpectError(ParsePly(with_header("ply\nformat ascii 1.0\nelement vertex 3\nproperty half x\n")),
              kInvalid, {"line 4", "unknown property type 'half'"});
  ExpectError(ParsePly(with_header("ply\nformat ascii 1.0\nproperty float x\n")), kInvalid,
              {"line 3", "before any \"element\""});
  ExpectError(ParsePly(with_header("ply\nformat ascii 1.0\nelement vertex -3\n")), kInvalid,
              {"line 3", "element count '-3'"});
  ExpectError(ParsePly(with_header("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                   "property float y\nproperty float z\nproperty float nx\n")),
              kInvalid, {"only some of nx, ny, nz"});
  ExpectError(ParsePly(with_header("ply\nformat ascii 1.0\nelement vertex 3\n"
                                   "property list float int x\n")),
              kInvalid, {"line 4", "list count type 'float'"});
  ExpectError(ParsePly(with_header("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                   "property float x\n")),
              kInvalid, {"line 5", "second property 'x'"});
  ExpectError(ParsePly(with_header("ply\nformat ascii 1.0\ncolour red\n")), kInvalid,
              {"line 3", "unknown header keyword 'colour'"});
}

TEST(PlyErrors, AsciiListWithTooFewItems) {
  const std::string bytes =
      "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\n"
      "element vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
      "3 0 1\n0 0 0\n";
  ExpectError(ParsePly(bytes), kInvalid, {"line 10, face 0", "3 items but the line ends after 2"});
}

TEST(PlyErrors, TruncatedBinary) {
  const std::string bytes = SerializePly(MakeCloud(3, false), PlyEncoding::kBinaryLittleEndian);
  const std::size_t data = bytes.find("end_header\n") + 11;
  // Vertex 2's z starts at data + 64; 3 of its 8 bytes are there.
  ExpectError(ParsePly(bytes.substr(0, data + 67)), kInvalid,
              {"header declares 3 vertices (72 bytes) but only 67 bytes follow the header"});
  ExpectError(ParsePly(bytes.substr(0, data)), kInvalid, {"only 0 bytes follow the header"});
}

TEST(PlyErrors, TruncatedBinaryWithLists) {
  std::string bytes =
      "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n"
      "property float y\nproperty float z\nproperty list uchar float tags\nend_header\n";
  const std::size_t data = bytes.size();
  for (float value : {1.f, 2.f, 3.f}) Put(&bytes, PlyEncoding::kBinaryLittleEndian, value);
  Put<std::uint8_t>(&bytes, PlyEncoding::kBinaryLittleEndian, 0);
  for (float value : {4.f, 5.f, 6.f}) Put(&bytes, PlyEncoding::kBinaryLittleEndian, value);
  Put<std::uint8_t>(&bytes, PlyEncoding::kBinaryLittleEndian, 200);  // but no items follow
  ExpectError(ParsePly(bytes), kInvalid,
              {absl::StrCat("byte offset ", data + 13 + 13, ", vertex 1"),
               "ends inside property 'tags' (it needs 800 bytes, 0 are left)"});
}

TEST(PlyErrors, NegativeBinaryListCount) {
  std::string bytes =
      "ply\nformat binary_big_endian 1.0\nelement face 1\nproperty list char int idx\n"
      "element vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
  const std::size_t data = bytes.size();
  Put<std::int8_t>(&bytes, PlyEncoding::kBinaryBigEndian, -1);
  for (float value : {1.f, 2.f, 3.f}) Put(&bytes, PlyEncoding::kBinaryBigEndian, value);
  ExpectError(ParsePly(bytes), kInvalid,
              {absl::StrCat("byte offset ", data, ", face 0"), "negative count (-1)"});
}

TEST(PlyErrors, HugeDeclaredVertexCountFailsFast) {
  std::string bytes =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\n"
      "property float x\nproperty float y\nproperty float z\nend_header\n";
  bytes.append(36, '\0');
  ExpectError(ParsePly(bytes), kInvalid,
              {"header declares 1000000000000 vertices (12000000000000 bytes) but only 36 bytes "
               "follow the header"});
  ExpectError(ParsePly(absl::StrReplaceAll(bytes, {{"1000000000000", "18446744073709551615"}})),
              kInvalid, {"more than 18446744073709551615 bytes"});
  ExpectError(ParsePly(absl::StrReplaceAll(bytes, {{"1000000000000", "18446744073709551616"}})),
              kInvalid, {"line 3", "element count"});
}

TEST(PlyErrors, HugeCountOfAnotherElementFailsFast) {
  std::string bytes =
      "ply\nformat binary_little_endian 1.0\nelement face 4000000000\n"
      "property list uchar int vertex_indices\nelement vertex 1\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n";
  bytes.append(12, '\0');
  ExpectError(ParsePly(bytes), kInvalid,
              {"declares 4000000000 'face' elements (at least 4000000000 bytes)"});
}

TEST(PlyErrors, GarbageAfterBinaryData) {
  const std::string bytes = SerializePly(MakeCloud(3, false), PlyEncoding::kBinaryBigEndian);
  ExpectError(ParsePly(bytes + "garbage"), kInvalid,
              {absl::StrCat("byte offset ", bytes.size()), "7 unexpected bytes"});
  EXPECT_TRUE(ParsePly(bytes + "\n").ok());
}

// ---------------------------------------------------------------------------------------------
// PCD.

// A PCD with extra fields around x y z (padding, a double y, rgb, curvature, a COUNT 3 histogram)
// and a non-default VIEWPOINT, in ASCII and binary.
TEST(Pcd, SkipsOtherFieldsAndReadsTheViewpoint) {
  const std::string header =
      "# .PCD v0.7 - Point Cloud Data file format\nVERSION .7\n"
      "FIELDS _ x y z rgb normal_x normal_y normal_z curvature hist\n"
      "SIZE 1 4 8 4 4 4 4 4 4 2\nTYPE U F F F F F F F F I\nCOUNT 2 1 1 1 1 1 1 1 1 3\n"
      "WIDTH 2\nHEIGHT 1\nVIEWPOINT 1 2 3 0.7071 0 0.7071 0\nPOINTS 2\n";
  for (PcdEncoding encoding : {PcdEncoding::kAscii, PcdEncoding::kBinary}) {
    const PlyEncoding put =
        encoding == PcdEncoding::kAscii ? PlyEncoding::kAscii : PlyEncoding::kBinaryLittleEndian;
    std::string bytes =
        header + (encoding == PcdEncoding::kAscii ? "DATA ascii\n" : "DATA binary\n");
    for (int i = 0; i < 2; ++i) {
      Put<std::uint8_t>(&bytes, put, 9);
      Put<std::uint8_t>(&bytes, put, 9);
      Put<float>(&bytes, put, 0.5f + i);
      Put<double>(&bytes, put, -1.25 - i);
      Put<float>(&bytes, put, 2.75f);
      Put<float>(&bytes, put, 4.2e6f);  // rgb
      Put<float>(&bytes, put, 0.f);
      Put<float>(&bytes, put, i == 0 ? 3.f : 0.f);
      Put<float>(&bytes, put, i == 0 ? 4.f : -1.f);
      Put<float>(&bytes, put, 0.01f);  // curvature
      for (std::int16_t h : {-1, 2, 300}) Put(&bytes, put, h);
      EndInstance(&bytes, put);
    }
    SCOPED_TRACE(encoding == PcdEncoding::kAscii ? "ascii" : "binary");
    const absl::StatusOr<PointCloud> cloud = ParsePcd(bytes);
    ASSERT_TRUE(cloud.ok()) << cloud.status();
    ASSERT_EQ(cloud->size(), 2u);
    EXPECT_EQ(cloud->points[0], Vec3(0.5, -1.25, 2.75));
    EXPECT_EQ(cloud->points[1], Vec3(1.5, -2.25, 2.75));
    EXPECT_TRUE(cloud->normals[0].isApprox(Vec3(0, 0.6, 0.8), 1e-15));
    EXPECT_EQ(cloud->normals[1], Vec3(0, 0, -1));
    ASSERT_TRUE(cloud->viewpoint.has_value());
    EXPECT_EQ(*cloud->viewpoint, Vec3(1, 2, 3));
  }
}

TEST(Pcd, DefaultsCountAndHeightAndAcceptsOldVersion) {
  const absl::StatusOr<PointCloud> cloud = ParsePcd(
      "VERSION 0.6\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nPOINTS 2\nDATA ascii\n"
      "1 2 3\n4 5 6\n");
  ASSERT_TRUE(cloud.ok()) << cloud.status();
  EXPECT_EQ(cloud->size(), 2u);
  EXPECT_FALSE(cloud->viewpoint.has_value());
}

// A greedy LZF compressor (liblzf's format) for the tests: back references of 3 to 264 bytes
// found in the last 2 KiB, literal runs of up to 32 bytes otherwise.
std::string LzfCompress(std::string_view in) {
  std::string out, literal;
  const auto flush = [&] {
    for (std::size_t at = 0; at < literal.size(); at += 32) {
      const std::size_t n = std::min<std::size_t>(32, literal.size() - at);
      out += static_cast<char>(n - 1);
      out += literal.substr(at, n);
    }
    literal.clear();
  };
  for (std::size_t i = 0; i < in.size();) {
    std::size_t best = 0, distance = 0;
    for (std::size_t d = 1; d <= std::min<std::size_t>(i, 2048); ++d) {
      std::size_t length = 0;
      while (i + length < in.size() && length < 264 && in[i + length] == in[i - d + length]) {
        ++length;
      }
      if (length > best) best = length, distance = d;
    }
    if (best < 3) {
      literal += in[i++];
      continue;
    }
    flush();
    const std::size_t length = best - 2, offset = distance - 1;
    out += static_cast<char>((std::min<std::size_t>(length, 7) << 5) | (offset >> 8));
    if (length >= 7) out += static_cast<char>(length - 7);
    out += static_cast<char>(offset & 0xff);
    i += best;
  }
  flush();
  return out;
}

void AppendWord(std::uint32_t word, std::string* out) {
  for (int k = 0; k < 4; ++k) *out += static_cast<char>((word >> (8 * k)) & 0xff);
}

// SerializePcd's binary file as PCL writes it compressed: the fields one after the other
// (sizes: 8 bytes per coordinate and normal component, 4 for rgb), LZF-compressed after their
// two sizes.
std::string CompressedPcd(const PointCloud& cloud) {
  const std::string binary = SerializePcd(cloud, PcdEncoding::kBinary);
  const std::size_t data = binary.find("DATA binary\n") + 12;
  std::vector<std::size_t> sizes(cloud.has_normals() ? 6 : 3, 8);
  if (cloud.has_colors()) sizes.push_back(4);
  std::size_t record = 0;
  for (std::size_t size : sizes) record += size;
  std::string fields;
  for (std::size_t f = 0, offset = 0; f < sizes.size(); offset += sizes[f++]) {
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      fields += binary.substr(data + i * record + offset, sizes[f]);
    }
  }
  const std::string compressed = LzfCompress(fields);
  std::string out =
      absl::StrReplaceAll(binary.substr(0, data), {{"DATA binary\n", "DATA binary_compressed\n"}});
  AppendWord(static_cast<std::uint32_t>(compressed.size()), &out);
  AppendWord(static_cast<std::uint32_t>(fields.size()), &out);
  return out + compressed;
}

// PCL's default for large clouds; it was refused as unimplemented.
TEST(Pcd, ReadsBinaryCompressedData) {
  for (bool with_normals : {false, true}) {
    PointCloud cloud = MakeCloud(300, with_normals);
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      cloud.colors.push_back({static_cast<std::uint8_t>(i % 7), 10, 200});
      if (i >= 3 && i % 5 == 0) cloud.points[i] = cloud.points[i - 1];  // repeats to compress
    }
    const std::string bytes = CompressedPcd(cloud);
    ASSERT_NE(bytes.find("DATA binary_compressed\n"), std::string::npos);
    const absl::StatusOr<PointCloud> parsed = ParsePcd(bytes);
    ASSERT_TRUE(parsed.ok()) << parsed.status();
    ExpectBitExact(*parsed, cloud);
  }
  // The decompressor copies overlapping back references byte by byte (a run of one value).
  PointCloud flat;
  flat.points.assign(40, Vec3(1.5, 1.5, 1.5));
  const absl::StatusOr<PointCloud> parsed = ParsePcd(CompressedPcd(flat));
  ASSERT_TRUE(parsed.ok()) << parsed.status();
  EXPECT_EQ(parsed->points, flat.points);
}

TEST(PcdErrors, DamagedCompressedDataIsRefusedNamingTheCause) {
  const std::string good = CompressedPcd(MakeCloud(20, false));
  const std::size_t data = good.find("DATA binary_compressed\n") + 23;
  std::string sizes_only = good.substr(0, data + 4);
  ExpectError(ParsePcd(sizes_only), kInvalid, {"must start with its compressed and uncompressed"});
  const auto with_sizes = [&](std::uint32_t compressed, std::uint32_t uncompressed) {
    std::string bytes = good.substr(0, data);
    AppendWord(compressed, &bytes);
    AppendWord(uncompressed, &bytes);
    return bytes + good.substr(data + 8);
  };
  const std::uint32_t compressed = static_cast<std::uint32_t>(good.size() - data - 8);
  ExpectError(ParsePcd(with_sizes(compressed + 1, 480)), kInvalid,
              {"compressed data are declared as"});
  ExpectError(ParsePcd(with_sizes(compressed, 488)), kInvalid,
              {"uncompressed size 488 is not POINTS x 24"});
  ASSERT_TRUE(ParsePcd(with_sizes(compressed, 480)).ok());
  std::string back = good;  // a back reference before the start of the output
  back[data + 8] = static_cast<char>(0xe0);
  ExpectError(ParsePcd(back), kInvalid, {"LZF data corrupt at byte 0", "before the start"});
  ExpectError(ParsePcd(good.substr(0, data + 8) + std::string(1, '\x1f') + "abc"), kInvalid,
              {"compressed data are declared as"});
  std::string huge = good.substr(0, data);  // 4 GB from a handful of bytes
  huge = absl::StrReplaceAll(huge,
                             {{"WIDTH 20", "WIDTH 178956970"}, {"POINTS 20", "POINTS 178956970"}});
  AppendWord(4, &huge);
  AppendWord(178956970u * 24u, &huge);
  ExpectError(ParsePcd(huge + "abcd"), kInvalid, {"LZF cannot expand 4 bytes"});
}

TEST(PcdErrors, UnknownVersion) {
  ExpectError(
      ParsePcd(absl::StrReplaceAll(AsciiPcd(kThreeVertices), {{"VERSION 0.7", "VERSION 2"}})),
      absl::StatusCode::kUnimplemented, {"line 2", "version '2'"});
}

TEST(PcdErrors, AllNanPointIsNamed) {
  ExpectError(ParsePcd(AsciiPcd("0 0 0\nnan nan nan\n0 1 0\n")), kInvalid,
              {"PCD line 13, point 1", "all NaN", "requires finite coordinates"});
  PointCloud cloud = MakeCloud(3, false);
  cloud.points[2] = Vec3::Constant(std::nan(""));
  const std::string bytes = SerializePcd(cloud, PcdEncoding::kBinary);
  ExpectError(ParsePcd(bytes), kInvalid,
              {absl::StrCat("PCD byte offset ", bytes.size() - 24, ", point 2"), "all NaN"});
}

TEST(PcdErrors, NonFiniteCoordinateOrNormal) {
  ExpectError(ParsePcd(AsciiPcd("0 0 0\n1 0 0\n0 inf 0\n")), kInvalid,
              {"line 14, point 2", "coordinate y is not finite"});
  PointCloud cloud = MakeCloud(3, true);
  cloud.normals[0] = Vec3(0, 0, 0);
  ExpectError(ParsePcd(SerializePcd(cloud, PcdEncoding::kAscii)), kInvalid,
              {"line 12, point 0", "zero length"});
}

TEST(PcdErrors, BadData) {
  ExpectError(ParsePcd(AsciiPcd("0 0 0\n1 0 0\n0 abc 0\n")), kInvalid,
              {"line 14, point 2", "field 'y'", "'abc' is not a number"});
  ExpectError(ParsePcd(AsciiPcd("0 0 0\n1 0\n0 1 0\n")), kInvalid,
              {"line 13, point 1", "ends before field 'z'"});
  ExpectError(ParsePcd(AsciiPcd("0 0 0\n1 0 0 1\n0 1 0\n")), kInvalid,
              {"line 13, point 1", "unexpected '1'"});
  ExpectError(ParsePcd(AsciiPcd("0.00 0.00 0.00\n1.00 0.00 0.00\n", 3)), kInvalid,
              {"line 13", "ends after 2 of the 3 points"});
  ExpectError(ParsePcd(AsciiPcd(absl::StrCat(kThreeVertices, "1 1 1\n"))), kInvalid,
              {"line 15", "unexpected data after the last point"});
  ExpectError(ParsePcd(AsciiPcd("", 0)), kInvalid, {"PCD file contains no points"});
}

TEST(PcdErrors, TruncatedOrHugeBinary) {
  const std::string bytes = SerializePcd(MakeCloud(3, false), PcdEncoding::kBinary);
  ExpectError(ParsePcd(bytes.substr(0, bytes.size() - 1)), kInvalid,
              {"byte offset", "header declares 3 points (72 bytes) but only 71 bytes follow"});
  ExpectError(ParsePcd(absl::StrReplaceAll(bytes, {{"WIDTH 3", "WIDTH 1000000000000"},
                                                   {"POINTS 3", "POINTS 1000000000000"}})),
              kInvalid, {"declares 1000000000000 points (24000000000000 bytes)"});
  ExpectError(ParsePcd(bytes + "xyz"), kInvalid, {"3 unexpected bytes"});
}

TEST(PcdErrors, HugeCountOrPointsInAsciiFailWithoutAllocating) {
  ExpectError(ParsePcd("FIELDS x y z h\nSIZE 4 4 4 1\nTYPE F F F U\n"
                       "COUNT 1 1 1 9223372036854775807\nPOINTS 1000000000000000\n"
                       "DATA ascii\n1 2 3 4\n"),
              kInvalid, {"line 7, point 0", "ends before field 'h'"});
  ExpectError(ParsePcd(AsciiPcd(kThreeVertices, 1000000000)), kInvalid,
              {"line 14", "ends after 3 of the 1000000000 points"});
}

TEST(PcdErrors, BadHeaders) {
  const std::string good = AsciiPcd(kThreeVertices);
  const auto replaced = [&good](const std::string& from, const std::string& to) {
    return ParsePcd(absl::StrReplaceAll(good, {{from, to}}));
  };
  ExpectError(replaced("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1",
                       "FIELDS x y\nSIZE 4 4\nTYPE F F\nCOUNT 1 1"),
              kInvalid, {"line 3", "FIELDS has no 'z'"});
  ExpectError(replaced("SIZE 4 4 4", "SIZE 4 4"), kInvalid,
              {"line 4", "SIZE has 2 values but FIELDS has 3"});
  ExpectError(replaced("TYPE F F F", "TYPE F F X"), kInvalid, {"line 5", "field 'z' has TYPE 'X'"});
  ExpectError(replaced("SIZE 4 4 4", "SIZE 4 4 2"), kInvalid, {"field 'z'", "SIZE '2'"});
  ExpectError(replaced("COUNT 1 1 1", "COUNT 1 1 2"), kInvalid,
              {"line 6", "field 'z' must have COUNT 1"});
  ExpectError(replaced("POINTS 3", "POINTS 4"), kInvalid,
              {"line 10", "POINTS is 4 but WIDTH * HEIGHT is 3"});
  ExpectError(replaced("VIEWPOINT 0 0 0 1 0 0 0", "VIEWPOINT 0 0 0 1 0 0"), kInvalid,
              {"line 9", "VIEWPOINT must have 7 numbers"});
  ExpectError(replaced("VIEWPOINT 0 0 0", "VIEWPOINT 0 nan 0"), kInvalid,
              {"line 9", "'nan' is not a finite number"});
  ExpectError(replaced("DATA ascii", "DATA text"), kInvalid, {"line 11", "unknown DATA"});
  ExpectError(ParsePcd(absl::StrReplaceAll(AsciiPcd(""), {{"DATA ascii\n", ""}})), kInvalid,
              {"no DATA line"});
  ExpectError(replaced("HEIGHT 1", "HEIGHT 1\nHEIGHT 1"), kInvalid, {"line 9", "second HEIGHT"});
  ExpectError(replaced("HEIGHT 1", "DEPTH 1"), kInvalid,
              {"line 8", "unknown header keyword 'DEPTH'"});
  ExpectError(ParsePcd(""), kInvalid, {"no DATA line"});
}

// ---------------------------------------------------------------------------------------------
// XYZ / CSV.

TEST(Xyz, ReadsCsvWithHeaderCommentsAndMixedSeparators) {
  const absl::StatusOr<PointCloud> cloud = ParseXyz(
      "x,y,z\r\n# a comment\n\n1,2,3\r\n  4 , 5\t,6  \n+7 -8e1 .5\n   # indented comment\n");
  ASSERT_TRUE(cloud.ok()) << cloud.status();
  ASSERT_EQ(cloud->size(), 3u);
  EXPECT_EQ(cloud->points[0], Vec3(1, 2, 3));
  EXPECT_EQ(cloud->points[1], Vec3(4, 5, 6));
  EXPECT_EQ(cloud->points[2], Vec3(7, -80, 0.5));
  EXPECT_FALSE(cloud->has_normals());
}

TEST(Xyz, NamedNormalsAreNormalised) {
  const absl::StatusOr<PointCloud> cloud = ParseXyz("x y z nx ny nz\n1 2 3 0 0 5\n4 5 6 0 -2 0\n");
  ASSERT_TRUE(cloud.ok()) << cloud.status();
  ASSERT_TRUE(cloud->has_normals());
  EXPECT_FALSE(cloud->has_colors());
  EXPECT_EQ(cloud->normals[0], Vec3(0, 0, 1));
  EXPECT_EQ(cloud->normals[1], Vec3(0, -1, 0));
}

absl::StatusOr<CloudFile> ParseText(std::string_view text, std::vector<std::string> columns = {}) {
  return ParseCloudFile(CloudFormat::kXyz, text, ReadOptions{std::move(columns)});
}

// CloudCompare exports "x y z r g b": the colours were read as normals and normalised.
TEST(Xyz, ColoursAreColoursWhetherNamedOrNot) {
  for (const char* text : {"//X,Y,Z,R,G,B\n1,2,3,255,0,10\n4,5,6,0,128,7\n",
                           "x y z red green blue\n1 2 3 255 0 10\n4 5 6 0 128 7\n",
                           "1 2 3 255 0 10\n4 5 6 0 128 7\n"}) {
    SCOPED_TRACE(text);
    const absl::StatusOr<CloudFile> file = ParseText(text);
    ASSERT_TRUE(file.ok()) << file.status();
    EXPECT_FALSE(file->cloud.has_normals());
    EXPECT_EQ(file->cloud.colors, (std::vector<Rgb>{{255, 0, 10}, {0, 128, 7}}));
    EXPECT_EQ(file->cloud.points[1], Vec3(4, 5, 6));
  }
  // Unnamed columns read from the data are said to be so.
  const absl::StatusOr<CloudFile> unnamed = ParseText("1 2 3 255 0 10\n");
  ASSERT_EQ(unnamed->notes.size(), 1u);
  EXPECT_THAT(unnamed->notes[0], HasSubstr("columns 4-6 read as colours r g b"));
  EXPECT_TRUE(ParseText("x y z r g b\n1 2 3 255 0 10\n")->notes.empty());
  // Unit vectors are normals, as mlsreg's own files without a header had them.
  const absl::StatusOr<CloudFile> normals = ParseText("1 2 3 0 0 1\n4 5 6 0.6 0.8 0\n");
  ASSERT_TRUE(normals.ok()) << normals.status();
  EXPECT_TRUE(normals->cloud.has_normals() && !normals->cloud.has_colors());
  EXPECT_THAT(normals->notes[0], HasSubstr("columns 4-6 read as normals nx ny nz"));
  // The columns given win over the data: axis-aligned "normals" named as colours.
  const absl::StatusOr<CloudFile> named =
      ParseText("1 2 3 0 0 1\n", {"x", "y", "z", "r", "g", "b"});
  ASSERT_TRUE(named.ok()) << named.status();
  EXPECT_EQ(named->cloud.colors, (std::vector<Rgb>{{0, 0, 1}}));
  // Floats in [0, 1] are scaled.
  const absl::StatusOr<CloudFile> unit = ParseText("x y z r g b\n1 2 3 1 0.5 0\n");
  ASSERT_TRUE(unit.ok()) << unit.status();
  EXPECT_EQ(unit->cloud.colors, (std::vector<Rgb>{{255, 128, 0}}));
  // Neither unit vectors nor colours: refused, saying how to name the columns.
  ExpectError(ParseXyz("1 2 3 0 0 5\n4 5 6 0 -2 0\n"), kInvalid,
              {"6 unnamed columns", "neither normals", "header line"});
  ExpectError(ParseXyz("x y z r g b\n1 2 3 300 0 0\n"), kInvalid,
              {"line 2, point 0", "colour r is 300"});
}

TEST(Xyz, ExtraColumnsAreReadIgnoredAndNamed) {
  const absl::StatusOr<CloudFile> intensity = ParseText("x y z intensity\n1 2 3 0.5\n4 5 6 9\n");
  ASSERT_TRUE(intensity.ok()) << intensity.status();
  EXPECT_EQ(intensity->cloud.size(), 2u);
  EXPECT_FALSE(intensity->cloud.has_normals() || intensity->cloud.has_colors());
  EXPECT_EQ(intensity->notes,
            std::vector<std::string>{"XYZ: columns read and ignored: intensity (column 4)"});
  const absl::StatusOr<CloudFile> unnamed = ParseText("1 2 3 0.5\n4 5 6 9\n");
  ASSERT_TRUE(unnamed.ok()) << unnamed.status();
  EXPECT_THAT(unnamed->notes[0], HasSubstr("column 4 ignored"));
  const absl::StatusOr<CloudFile> given =
      ParseText("1 2 3 0.5 7 0 0 1\n", {"x", "y", "z", "intensity", "label", "nx", "ny", "nz"});
  ASSERT_TRUE(given.ok()) << given.status();
  EXPECT_EQ(given->cloud.normals[0], Vec3(0, 0, 1));
  EXPECT_THAT(given->notes[0], HasSubstr("intensity (column 4), label (column 5)"));
  const absl::StatusOr<CloudFile> many = ParseText("1 2 3 4 5 6 7 8\n");
  ASSERT_TRUE(many.ok()) << many.status();
  EXPECT_THAT(many->notes[0], HasSubstr("columns 4, 5, 6, 7, 8 ignored"));
}

TEST(XyzErrors, ColumnNamesAndCounts) {
  ExpectError(ParseXyz("1 2 3\n4 5 6 7 8 9\n"), kInvalid,
              {"XYZ line 2, point 1", "has 6 fields but line 1 has 3"});
  ExpectError(ParseXyz("x y z\n1 2 3 4\n"), kInvalid,
              {"line 2, point 0", "has 4 fields but the header line names 3"});
  ExpectError(ParseXyz("1 2\n"), kInvalid, {"line 1", "has 2 columns"});
  ExpectError(ParseXyz("x y nz\n1 2 3\n"), kInvalid, {"header line", "does not name x, y and z"});
  ExpectError(ParseXyz("x y z nx\n1 2 3 4\n"), kInvalid, {"only some of nx, ny, nz"});
  ExpectError(ParseXyz("x y z x\n1 2 3 4\n"), kInvalid, {"names column 'x' twice"});
  ExpectError(ParseText("1 2 3\n", {"x", "y", "z", "r"}).status(), kInvalid,
              {"the columns given", "only some of r, g, b"});
}

TEST(XyzErrors, NonNumericTokens) {
  ExpectError(ParseXyz("1 2 3\n4 x 6\n"), kInvalid, {"line 2, point 1", "'x' is not a number"});
  ExpectError(ParseXyz("1 2 3\nx y z\n"), kInvalid, {"line 2", "'x' is not a number"});
  ExpectError(ParseXyz("1 2 abc\n"), kInvalid, {"line 1, point 0", "'abc'"});
  ExpectError(ParseXyz("1,,2,3\n"), kInvalid, {"line 1", "empty field"});
  ExpectError(ParseXyz(",1,2,3\n"), kInvalid, {"line 1", "empty field"});
  ExpectError(ParseXyz("1,2,3,\n"), kInvalid, {"line 1", "empty field"});
}

TEST(XyzErrors, NonFiniteOrEmpty) {
  ExpectError(ParseXyz("1 2 3\n4 5 inf\n"), kInvalid,
              {"line 2, point 1", "coordinate z is not finite"});
  ExpectError(ParseXyz("x y z nx ny nz\n1 2 3 0 0 0\n"), kInvalid,
              {"line 2, point 0", "zero length"});
  ExpectError(ParseXyz(""), kInvalid, {"XYZ file contains no points"});
  ExpectError(ParseXyz("x y z\n# nothing else\n\n"), kInvalid, {"contains no points"});
}

// ---------------------------------------------------------------------------------------------
// Files.

class FileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    directory_ = std::filesystem::temp_directory_path() /
                 absl::StrCat("mlsreg_io_test_", getpid(), "_",
                              ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(directory_);
  }
  void TearDown() override { std::filesystem::remove_all(directory_); }

  std::string PathOf(std::string_view name) const { return (directory_ / name).string(); }

  std::filesystem::path directory_;
};

TEST_F(FileTest, WritesAndReadsEveryExtension) {
  PointCloud cloud = MakeCloud(20, true);
  const WriteOptions ascii = {.ply = PlyEncoding::kAscii, .pcd = PcdEncoding::kAscii};
  const WriteOptions big_endian = {.ply = PlyEncoding::kBinaryBigEndian};
  const std::pair<std::string, WriteOptions> cases[] = {
      {"a.ply", {}},    {"b.PLY", ascii}, {"c.Ply", big_endian}, {"d.pcd", {}},
      {"e.PCD", ascii}, {"f.xyz", {}},    {"g.txt", {}},         {"h.CSV", {}}};
  for (const auto& [name, options] : cases) {
    SCOPED_TRACE(name);
    const std::string path = PathOf(name);
    ASSERT_TRUE(WritePointCloud(cloud, path, options).ok());
    const absl::StatusOr<PointCloud> read = ReadPointCloud(path);
    ASSERT_TRUE(read.ok()) << read.status();
    ExpectBitExact(*read, cloud);
  }
}

// A PLY with a scalar field and colours reads back as the same cloud (the extra properties are
// skipped), and its header and records hold the attributes where the PLY format puts them.
TEST_F(FileTest, PlyWithAttributesReadsBackAndCarriesScalarsAndColours) {
  PointCloud cloud = MakeCloud(5, true);
  PointAttributes attributes;
  attributes.scalars.emplace_back("distance_d", std::vector<float>{0.5f, 1.f, 2.f, 3.f, 4.25f});
  for (std::uint8_t i = 0; i < 5; ++i) cloud.colors.push_back({i, 100, 200});
  const std::string path = PathOf("attributed.ply");
  ASSERT_TRUE(WriteCloudWithAttributes(cloud, attributes, path).ok());
  const absl::StatusOr<CloudFile> read = ReadCloudFile(path);
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectBitExact(read->cloud, cloud);
  EXPECT_THAT(read->notes[0], HasSubstr("vertex properties read and ignored: distance_d"));
  const std::string bytes = *ReadFileBytes(path);
  const std::size_t body = bytes.find("end_header\n") + 11;
  EXPECT_NE(bytes.find("property double nz\nproperty float distance_d\nproperty uchar red\n"
                       "property uchar green\nproperty uchar blue\nend_header"),
            std::string::npos);
  constexpr std::size_t kRecord = 6 * 8 + 4 + 3;
  ASSERT_EQ(bytes.size(), body + 5 * kRecord);
  float last;
  std::memcpy(&last, bytes.data() + body + 4 * kRecord + 48, 4);  // little-endian host
  EXPECT_EQ(last, 4.25f);
  EXPECT_EQ(static_cast<std::uint8_t>(bytes[body + 4 * kRecord + 52]), 4);
  EXPECT_EQ(static_cast<std::uint8_t>(bytes[body + 4 * kRecord + 54]), 200);

  PointAttributes short_scalar;
  short_scalar.scalars.emplace_back("d", std::vector<float>{1.f});
  ExpectError(WriteCloudWithAttributes(cloud, short_scalar, path), kInvalid, {"'d'", "one value"});
  PointAttributes taken;
  taken.scalars.emplace_back("red", std::vector<float>(5, 0.f));
  ExpectError(WriteCloudWithAttributes(cloud, taken, path), kInvalid, {"'red'"});
  PointCloud few_colours = cloud;
  few_colours.colors.resize(2);
  ExpectError(WriteCloudWithAttributes(few_colours, {}, path), kInvalid, {"colours"});
  ExpectError(WriteCloudWithAttributes(cloud, {}, PathOf("a.obj")), kInvalid, {"'.obj'"});
}

// The same in every other format the extension names: the scalars are columns (or fields) named
// where the format names them, and the cloud reads back.
TEST_F(FileTest, AttributesInPcdXyzCsvAndNpy) {
  PointCloud cloud = MakeCloud(4, false);
  for (std::uint8_t i = 0; i < 4; ++i) cloud.colors.push_back({i, 50, 250});
  PointAttributes attributes;
  attributes.scalars.emplace_back("distance_d", std::vector<float>{0.5f, 1.f, 2.f, 1e-3f});
  for (const char* name : {"a.pcd", "b.xyz", "c.csv", "d.txt"}) {
    SCOPED_TRACE(name);
    const std::string path = PathOf(name);
    ASSERT_TRUE(WriteCloudWithAttributes(cloud, attributes, path).ok());
    const absl::StatusOr<CloudFile> read = ReadCloudFile(path);
    ASSERT_TRUE(read.ok()) << read.status();
    ExpectBitExact(read->cloud, cloud);
    EXPECT_THAT(read->notes[0], HasSubstr("distance_d"));
  }
  EXPECT_THAT(*ReadFileBytes(PathOf("a.pcd")),
              HasSubstr("FIELDS x y z distance_d rgb\nSIZE 8 8 8 4 4\nTYPE F F F F F\n"));
  EXPECT_THAT(*ReadFileBytes(PathOf("b.xyz")), StartsWith("x y z distance_d r g b\n"));
  EXPECT_THAT(*ReadFileBytes(PathOf("c.csv")), StartsWith("x,y,z,distance_d,r,g,b\n"));
  const std::string npy = PathOf("e.npy");
  ASSERT_TRUE(WriteCloudWithAttributes(cloud, attributes, npy).ok());
  EXPECT_THAT(*ReadFileBytes(npy), HasSubstr("'shape': (4, 7)"));
  const absl::StatusOr<CloudFile> read =
      ReadCloudFile(npy, ReadOptions{{"x", "y", "z", "distance_d", "r", "g", "b"}});
  ASSERT_TRUE(read.ok()) << read.status();
  ExpectBitExact(read->cloud, cloud);
}

TEST_F(FileTest, MissingFileIsNotFound) {
  const std::string path = PathOf("missing.ply");
  ExpectError(ReadPointCloud(path), absl::StatusCode::kNotFound, {path});
  ExpectError(ReadPointCloud(PathOf("no_such_dir/x.pcd")), absl::StatusCode::kNotFound,
              {"no_such_dir/x.pcd"});
}

TEST_F(FileTest, UnknownOrMissingExtensionIsInvalidArgument) {
  ExpectError(ReadPointCloud(PathOf("cloud.foo")), kInvalid, {"'.foo'", "cloud.foo"});
  ExpectError(ReadPointCloud(PathOf("cloud")), kInvalid, {"no file extension"});
  ExpectError(ReadPointCloud(PathOf("dir.ply/cloud")), kInvalid, {"no file extension"});
  EXPECT_EQ(WritePointCloud(MakeCloud(3, false), PathOf("cloud.obj")).code(), kInvalid);
}

TEST_F(FileTest, UnreadablePathIsUnavailable) {
  const std::string path = PathOf("a_directory.xyz");
  std::filesystem::create_directories(path);
  ExpectError(ReadPointCloud(path), absl::StatusCode::kUnavailable, {path});
}

TEST_F(FileTest, ParseErrorsArePrefixedWithThePath) {
  const std::string path = PathOf("bad.pcd");
  std::ofstream(path) << "VERSION 2\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\n"
                         "DATA binary\n";
  const absl::StatusOr<PointCloud> result = ReadPointCloud(path);
  ExpectError(result, absl::StatusCode::kUnimplemented, {"line 1"});
  EXPECT_THAT(std::string(result.status().message()), StartsWith(path + ": PCD line 1: "));
}

TEST_F(FileTest, WriteRejectsInvalidCloudsAndMissingDirectories) {
  EXPECT_EQ(WritePointCloud(PointCloud{}, PathOf("empty.ply")).code(), kInvalid);
  PointCloud nan_cloud = MakeCloud(3, false);
  nan_cloud.points[1].x() = std::nan("");
  const absl::Status status = WritePointCloud(nan_cloud, PathOf("nan.xyz"));
  EXPECT_EQ(status.code(), kInvalid);
  EXPECT_THAT(std::string(status.message()), HasSubstr("point 1"));
  const absl::Status no_dir = WritePointCloud(MakeCloud(3, false), PathOf("nope/a.ply"));
  EXPECT_EQ(no_dir.code(), absl::StatusCode::kNotFound);
  EXPECT_THAT(std::string(no_dir.message()), HasSubstr("nope/a.ply"));
}

// ---------------------------------------------------------------------------------------------
// Mutation test: random damage to valid files must give OK (a valid cloud) or an error, never a
// crash, a hang or an invalid cloud.

std::string Mutate(std::string bytes, std::mt19937& random) {
  static constexpr char kBytes[] = "0123456789 \n\r\t.,-+eEnaif#\0\xff";
  static constexpr std::string_view kInteresting(kBytes, sizeof(kBytes) - 1);
  const auto position = [&](std::size_t size) {
    return std::uniform_int_distribution<std::size_t>(0, size)(random);
  };
  const auto some_byte = [&] {
    if (random() % 2 == 0) return kInteresting[random() % kInteresting.size()];
    return static_cast<char>(random() % 256);
  };
  const int operations = 1 + static_cast<int>(random() % 3);
  for (int i = 0; i < operations && !bytes.empty(); ++i) {
    switch (random() % 4) {
      case 0:  // Overwrite a byte.
        bytes[position(bytes.size() - 1)] = some_byte();
        break;
      case 1:  // Truncate.
        bytes.resize(position(bytes.size()));
        break;
      case 2: {  // Insert garbage.
        std::string garbage(1 + random() % 8, ' ');
        for (char& c : garbage) c = some_byte();
        bytes.insert(position(bytes.size()), garbage);
        break;
      }
      default:  // Delete a run.
        bytes.erase(position(bytes.size()), 1 + random() % 16);
        break;
    }
  }
  return bytes;
}

void RunMutations(const std::string& original,
                  const std::function<absl::StatusOr<PointCloud>(std::string_view)>& parse,
                  std::uint32_t seed) {
  std::mt19937 random(seed);
  int accepted = 0;
  int rejected = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const std::string mutated = Mutate(original, random);
    const absl::StatusOr<PointCloud> result = parse(mutated);
    if (!result.ok()) {
      ++rejected;
      ASSERT_FALSE(result.status().message().empty());
      continue;
    }
    ++accepted;
    ASSERT_TRUE(ValidatePointCloud(*result, 1).ok()) << "trial " << trial;
    for (const Vec3& normal : result->normals) {
      ASSERT_NEAR(normal.norm(), 1.0, 1e-12) << "trial " << trial;
    }
  }
  EXPECT_GT(accepted, 0);
  EXPECT_GT(rejected, 1000);
}

TEST(Mutation, BinaryPly) {
  RunMutations(SerializePly(MakeCloud(50, true), PlyEncoding::kBinaryLittleEndian), ParsePly, 1);
}

TEST(Mutation, AsciiPly) {
  RunMutations(SerializePly(MakeCloud(50, false), PlyEncoding::kAscii), ParsePly, 2);
}

TEST(Mutation, AsciiPcd) {
  RunMutations(SerializePcd(MakeCloud(50, true), PcdEncoding::kAscii), ParsePcd, 3);
}

TEST(Mutation, BinaryPcd) {
  RunMutations(SerializePcd(MakeCloud(50, false), PcdEncoding::kBinary), ParsePcd, 4);
}

TEST(Mutation, Xyz) { RunMutations(SerializeXyz(MakeCloud(50, true)), ParseXyz, 5); }

TEST(Mutation, CompressedPcd) {
  PointCloud cloud = MakeCloud(50, true);
  cloud.colors.assign(cloud.size(), Rgb{1, 2, 3});
  RunMutations(CompressedPcd(cloud), ParsePcd, 6);
}

}  // namespace
}  // namespace mlsreg
