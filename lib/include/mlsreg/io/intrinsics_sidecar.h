// The .intrinsics sidecar that marks a scan file as an organised pinhole scan (reverse
// calibration, mlsreg/geometry/depth_grid.h).
#pragma once

#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "mlsreg/core/point_cloud.h"

namespace mlsreg {

// The sidecar of a scan file: `<path>.intrinsics`, a text file holding the six numbers
// "width height fx fy cx cy" (whitespace separated; '#' starts a comment). NotFound when absent.
absl::StatusOr<PinholeIntrinsics> ReadIntrinsicsSidecar(const std::string& scan_path);
// The sidecar's text; `source` names it in messages.
absl::StatusOr<PinholeIntrinsics> ParseIntrinsics(std::string_view text, std::string_view source);
std::string FormatIntrinsics(const PinholeIntrinsics& k);

}  // namespace mlsreg
