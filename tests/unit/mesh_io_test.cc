// Triangle-mesh readers (OFF, OBJ, PLY faces) and the NumPy .npy point reader.
#include "mlsreg/io/mesh_io.h"

#include <cstdio>
#include <fstream>
#include <string>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "mlsreg/core/triangle_mesh.h"
#include "mlsreg/io/io.h"

namespace mlsreg {
namespace {

using ::testing::HasSubstr;

TEST(OffTest, ReadsQuadAsTwoTrianglesWithCommentsAndColours) {
  const auto mesh = ParseOff(
      "OFF\n# a unit square\n4 1 0\n0 0 0\n1 0 0\n1 1 0 # corner\n0 1 0\n4 0 1 2 3 255 0 0\n");
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  ASSERT_EQ(mesh->vertices.size(), 4u);
  ASSERT_EQ(mesh->triangles.size(), 2u);
  EXPECT_EQ(mesh->triangles[0], (std::array<std::uint32_t, 3>{0, 1, 2}));
  EXPECT_EQ(mesh->triangles[1], (std::array<std::uint32_t, 3>{0, 2, 3}));
  EXPECT_TRUE(mesh->SurfaceCentroid().isApprox(Vec3(0.5, 0.5, 0.0)));
}

TEST(OffTest, CountsOnTheMagicLineAreAccepted) {
  const auto mesh = ParseOff("OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(mesh->triangles.size(), 1u);
}

TEST(OffTest, BadIndexNamesTheFace) {
  const auto mesh = ParseOff("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
  ASSERT_FALSE(mesh.ok());
  EXPECT_EQ(mesh.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(mesh.status().message(), HasSubstr("face 0"));
  EXPECT_THAT(mesh.status().message(), HasSubstr("7"));
}

TEST(OffTest, TruncatedFileSaysWhatIsMissing) {
  const auto mesh = ParseOff("OFF\n3 1 0\n0 0 0\n1 0 0\n");
  ASSERT_FALSE(mesh.ok());
  EXPECT_THAT(mesh.status().message(), HasSubstr("2 of 3 vertices"));
}

TEST(OffTest, NonFiniteCoordinateIsRefused) {
  const auto mesh = ParseOff("OFF\n3 1 0\n0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n");
  ASSERT_FALSE(mesh.ok());
  EXPECT_THAT(mesh.status().message(), HasSubstr("vertex 1"));
}

TEST(ObjTest, ReadsSlashCornersAndNegativeIndices) {
  const auto mesh = ParseObj(
      "# cube corner\nv 0 0 0\nv 1 0 0\nv 1 1 0\nvn 0 0 1\nvt 0 0\nf 1/1/1 2//1 3\nv 0 1 0\n"
      "f -4 -2 -1\n");
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  ASSERT_EQ(mesh->triangles.size(), 2u);
  EXPECT_EQ(mesh->triangles[0], (std::array<std::uint32_t, 3>{0, 1, 2}));
  EXPECT_EQ(mesh->triangles[1], (std::array<std::uint32_t, 3>{0, 2, 3}));
}

TEST(ObjTest, ReferenceToMissingVertexIsRefused) {
  const auto mesh = ParseObj("v 0 0 0\nv 1 0 0\nf 1 2 3\n");
  ASSERT_FALSE(mesh.ok());
  EXPECT_THAT(mesh.status().message(), HasSubstr("not one of the 2 vertices"));
}

TEST(PlyMeshTest, AsciiFacesWithExtraVertexProperties) {
  const auto mesh = ParsePlyMesh(
      "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
      "property float z\nproperty float confidence\nelement face 1\n"
      "property list uchar int vertex_indices\nend_header\n0 0 0 1\n2 0 0 1\n2 2 0 1\n0 2 0 1\n"
      "4 0 1 2 3\n");
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(mesh->triangles.size(), 2u);
  EXPECT_DOUBLE_EQ(mesh->BoundingRadius(Vec3(1, 1, 0)), std::sqrt(2.0));
}

TEST(PlyMeshTest, BinaryFaces) {
  std::string ply =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
      "property float y\nproperty float z\nelement face 1\n"
      "property list uchar uint vertex_indices\nend_header\n";
  const float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  ply.append(reinterpret_cast<const char*>(xyz), sizeof(xyz));
  ply += '\x03';
  const std::uint32_t corners[3] = {2, 1, 0};
  ply.append(reinterpret_cast<const char*>(corners), sizeof(corners));
  const auto mesh = ParsePlyMesh(ply);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  ASSERT_EQ(mesh->triangles.size(), 1u);
  EXPECT_EQ(mesh->triangles[0], (std::array<std::uint32_t, 3>{2, 1, 0}));
}

TEST(PlyMeshTest, PointCloudWithoutFacesIsNotAMesh) {
  const auto mesh = ParsePlyMesh(
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
      "property float z\nend_header\n0 0 0\n");
  ASSERT_FALSE(mesh.ok());
  EXPECT_THAT(mesh.status().message(), HasSubstr("not a mesh"));
}

TEST(ReadTriangleMeshTest, StanfordBunnyReconstruction) {
  const auto mesh = ReadTriangleMesh(std::string(MLSREG_SHARED_DATA_DIR) +
                                     "/stanford_bunny/reconstruction/bun_zipper.ply");
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(mesh->vertices.size(), 35947u);
  EXPECT_EQ(mesh->triangles.size(), 69451u);
}

TEST(ReadTriangleMeshTest, UnknownExtensionAndMissingFile) {
  EXPECT_EQ(ReadTriangleMesh("mesh.stl").status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ReadTriangleMesh("/nonexistent/mesh.off").status().code(), absl::StatusCode::kNotFound);
}

TEST(NpyTest, RoundTripsThroughAFile) {
  PointCloud cloud;
  cloud.points = {Vec3(1, 2, 3), Vec3(-4.5, 0.25, 1e-9)};
  const std::string path = ::testing::TempDir() + "/cloud.npy";
  ASSERT_TRUE(WritePointCloud(cloud, path).ok());
  const auto read = ReadPointCloud(path);
  ASSERT_TRUE(read.ok()) << read.status();
  ASSERT_EQ(read->size(), 2u);
  EXPECT_EQ(read->points[1], cloud.points[1]);
  std::remove(path.c_str());
}

TEST(NpyTest, ReadsFloat32WithNormalsAndVersion2Header) {
  std::string dict = "{'descr': '<f4', 'fortran_order': False, 'shape': (1, 6), }";
  dict.append(64 - (12 + dict.size() + 1) % 64, ' ');
  dict += '\n';
  std::string npy = std::string("\x93NUMPY\x02\x00", 8);
  const std::uint32_t length = static_cast<std::uint32_t>(dict.size());
  npy.append(reinterpret_cast<const char*>(&length), 4);
  npy += dict;
  const float values[6] = {1, 2, 3, 0, 0, 1};
  npy.append(reinterpret_cast<const char*>(values), sizeof(values));
  const auto cloud = ParseNpy(npy);
  ASSERT_TRUE(cloud.ok()) << cloud.status();
  EXPECT_EQ(cloud->points[0], Vec3(1, 2, 3));
  ASSERT_TRUE(cloud->has_normals());
  EXPECT_EQ(cloud->normals[0], Vec3(0, 0, 1));
}

TEST(NpyTest, RefusesWrongShapeTypeAndLength) {
  auto make = [](const std::string& descr, const std::string& shape, std::size_t data_bytes) {
    std::string dict =
        "{'descr': '" + descr + "', 'fortran_order': False, 'shape': " + shape + ", }\n";
    std::string npy = std::string("\x93NUMPY\x01\x00", 8);
    npy += static_cast<char>(dict.size());
    npy += '\0';
    return npy + dict + std::string(data_bytes, '\0');
  };
  EXPECT_THAT(ParseNpy(make("<f8", "(2, 2)", 32)).status().message(), HasSubstr("3 <= k"));
  EXPECT_THAT(ParseNpy(make("<f8", "(2, 3, 1)", 48)).status().message(), HasSubstr("(N, k)"));
  EXPECT_EQ(ParseNpy(make("<i4", "(1, 3)", 12)).status().code(), absl::StatusCode::kUnimplemented);
  EXPECT_THAT(ParseNpy(make("<f8", "(2, 3)", 40)).status().message(), HasSubstr("40 bytes follow"));
  EXPECT_EQ(ParseNpy("not numpy").status().code(), absl::StatusCode::kInvalidArgument);
}

// An NPY array's columns are read as a text file's without a header: (N, 6) holds normals or
// colours as the values show, further columns are ignored and said, and named columns win.
TEST(NpyTest, ColumnsBeyondXyzAreNormalsColoursOrIgnored) {
  PointCloud cloud;
  cloud.points = {Vec3(1, 2, 3), Vec3(4, 5, 6)};
  cloud.normals = {Vec3(0, 0, 2), Vec3(0, 1, 1)};  // not unit: written as they are
  const absl::StatusOr<CloudFile> colours = ParseCloudFile(CloudFormat::kNpy, SerializeNpy(cloud));
  ASSERT_TRUE(colours.ok()) << colours.status();
  EXPECT_EQ(colours->cloud.colors, (std::vector<Rgb>{{0, 0, 2}, {0, 1, 1}}));
  EXPECT_THAT(colours->notes[0], HasSubstr("read as colours r g b"));
  const absl::StatusOr<CloudFile> named = ParseCloudFile(
      CloudFormat::kNpy, SerializeNpy(cloud), ReadOptions{{"x", "y", "z", "nx", "ny", "nz"}});
  ASSERT_TRUE(named.ok()) << named.status();
  EXPECT_TRUE(named->notes.empty());
  EXPECT_EQ(named->cloud.normals[0], Vec3(0, 0, 1));
  EXPECT_EQ(ParseCloudFile(CloudFormat::kNpy, SerializeNpy(cloud), ReadOptions{{"x", "y", "z"}})
                .status()
                .message(),
            "NPY: the columns given name 3 columns but the array has 6");
}

TEST(NpyTest, ThreeDMatchDemoFragment) {
  const auto cloud =
      ReadPointCloud(std::string(MLSREG_SHARED_DATA_DIR) + "/3dmatch_geotransformer_demo/src.npy");
  ASSERT_TRUE(cloud.ok()) << cloud.status();
  EXPECT_EQ(cloud->size(), 15953u);
}

}  // namespace
}  // namespace mlsreg
