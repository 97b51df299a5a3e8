// Registration results as clouds a person can open (CloudCompare, MeshLab): the aligned source
// coloured by its distance to the target's MLS surface, and source and target merged.
#pragma once

#include <string>

#include "absl/status/status.h"
#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/transform.h"
#include "mlsreg/geometry/target.h"

namespace mlsreg::cli {

// Distances at and beyond this (units of d) are red on the colour ramp (blue 0, green half way).
inline constexpr double kDistanceRampMaxD = 3.0;

// The source under `transform` with a scalar field `distance_d` (its distance to the target's
// MLS surface in units of d) and its own colours, or when it has none the distance as a
// blue-green-red colour ramp, in the format `path`'s extension names (PLY, PCD, XYZ/CSV, NPY:
// WriteCloudWithAttributes; NPY columns x y z [nx ny nz] distance_d r g b).
absl::Status WriteAlignedCloud(const std::string& path, const PointCloud& source,
                               const Matrix4& transform, const Target& target);

// The source under `transform` (orange) and the target (blue) in the target's frame, with a
// scalar field `cloud` (0 source, 1 target), in the format `path`'s extension names (NPY
// columns x y z cloud r g b).
absl::Status WriteMergedCloud(const std::string& path, const PointCloud& source,
                              const Matrix4& transform, const Target& target);

}  // namespace mlsreg::cli
