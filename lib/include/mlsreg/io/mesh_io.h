// Reading triangle meshes from OFF, OBJ or PLY files.
//
// Polygons with more than three corners are split into a fan of triangles; degenerate triangles
// (a repeated corner) are kept, since a ray never hits them. Readers check every index against
// the vertex count and every coordinate for finiteness, and name the line (or byte offset) of a
// problem, as the point-cloud readers do.
//   OFF  "OFF" (optionally with C/N/ST prefixes, whose extra vertex values are skipped), counts
//        line "vertices faces edges", vertex lines, then "n i1 ... in" face lines. '#' comments.
//   OBJ  "v x y z [w]" and "f a b c ..." lines, where a corner may be "i", "i/t", "i//n" or
//        "i/t/n" and negative indices count from the end; other statements are ignored.
//   PLY  As ParsePly, plus a "face" element with a "vertex_indices" (or "vertex_index") list.
#pragma once

#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "mlsreg/core/triangle_mesh.h"

namespace mlsreg {

absl::StatusOr<TriangleMesh> ParseOff(std::string_view bytes);
absl::StatusOr<TriangleMesh> ParseObj(std::string_view bytes);
absl::StatusOr<TriangleMesh> ParsePlyMesh(std::string_view bytes);

// Reads a mesh choosing the format by extension (.off, .obj, .ply; case-insensitive). Errors as
// ReadPointCloud: InvalidArgument for an unknown extension or bad data (prefixed with the path),
// NotFound / Unavailable for a missing or unreadable file.
absl::StatusOr<TriangleMesh> ReadTriangleMesh(const std::string& path);

}  // namespace mlsreg
