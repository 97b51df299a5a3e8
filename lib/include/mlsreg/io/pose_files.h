// Pose files of multi-view alignment: one pose per scan, each mapping the scan's points into the
// common frame (p_common = R p_scan + t). Two formats:
//  - rows: 16 row-major numbers per line (spaces or commas), one line per scan in scan order;
//    lines starting with '#' and blank lines are skipped;
//  - Stanford .conf (the bunny's bun.conf, the dragon's dragonStandRight.conf): lines
//    `bmesh <file> tx ty tz qi qj qk qr`, matched to scans by file name; `camera` and `mesh`
//    lines are ignored. The scanalyze convention these files use: the rotation is R(q)^T, the
//    transpose of the Hamilton rotation of q = (qi, qj, qk, qr) as written, then t is added.
#pragma once

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "mlsreg/core/transform.h"

namespace mlsreg {

// Reads `path` (a .conf by extension, else rows) and returns one pose per entry of
// `scan_paths` (a .conf is matched by file name, without directories). InvalidArgument naming
// the line for a malformed or non-rigid pose, a count that is not the scans', or a scan the
// .conf does not list.
absl::StatusOr<std::vector<Matrix4>> ReadPoses(const std::string& path,
                                               const std::vector<std::string>& scan_paths);
absl::StatusOr<std::vector<Matrix4>> ParsePoseRows(std::string_view text, std::size_t count);
absl::StatusOr<std::vector<Matrix4>> ParseStanfordConf(std::string_view text,
                                                       const std::vector<std::string>& scan_paths);

std::string FormatPoseRows(const std::vector<Matrix4>& poses);
std::string FormatStanfordConf(const std::vector<Matrix4>& poses,
                               const std::vector<std::string>& scan_paths);
// By extension, as ReadPoses.
absl::Status WritePoses(const std::string& path, const std::vector<Matrix4>& poses,
                        const std::vector<std::string>& scan_paths);

}  // namespace mlsreg
