// The rival search: whether another pose along a verified result's weakest direction explains
// the source as well (a corridor whose doors and pillars repeat). The data of such a scene fix
// the pose only up to the repeats, and no test at the returned pose tells it from its alias: only
// finding the other pose can. The result is moved along its weakest direction (and, when that is
// a rotation, along its weakest translation too: a corridor's slide) by one and two final capture
// ranges of the coarse alignment (2 and 4 working voxels) both ways, the voxel clouds are aligned
// again from there and each probe is verified. A probe that verifies, is only pulled, fails only
// on its weakest direction or is only seen through (what it lays where the target's beams passed
// may have moved: traffic), explains nearly as much of what the target's sensor could see, and
// ends clearly elsewhere is a rival, and the result is `ambiguous` (docs/verification.md,
// "Rivals").
#pragma once

#include <functional>
#include <optional>
#include <vector>

#include "mlsreg/geometry/voxel_cloud.h"
#include "mlsreg/registration/result.h"
#include "mlsreg/registration/verification.h"

namespace mlsreg::internal {

// Whether a verified `score` rests on so little information along its weakest direction that
// a rival is searched for: worst_direction_strength (about the share of the overlap's surface
// that faces the direction) under 0.02, or, where that direction is a rotation, the weakest
// translation's strength under 0.02. Corridors carry 0.0015-0.0092 and the open road
// 0.0009-0.0037 at their verified results, streets 0.003-0.12 (56 % of them are searched, none
// had a rival) and KITTI 0.035-0.082.
bool SearchesForRival(const VerificationScore& score);

struct RivalSearch {
  std::vector<AutoCandidate> probes;  // origin kRival, in the order tried
  std::optional<int> rival;           // the probe that is a rival (the search ends there)
  bool cancelled = false;             // an alignment was cancelled: the search ended there
  double seconds = 0.0;
};

// How far the probes reach along the weakest direction, in final capture ranges of the coarse
// alignment, both ways.
enum class RivalReach {
  kNear,  // 1 and 2: a result aligned from the caller's start
  // Also 4 and 8: a pose that may come from anywhere (a result of auto's global stage or of FGR,
  // a pose given to verify), which can be any alias along the direction.
  // A corridor scanned densely (150 beams over +-45 degrees, 5 mm noise), from the identity: a
  // global candidate 6.5 m along the corridor verified, its near probes all came back, and the
  // probe 4 ranges (3.9 m) away explained 96 % as much.
  kFar,
};

// Searches for a rival of `result`, verified with `score` on `source_voxels` (the source's voxel
// cloud at the target's working voxel), as far as `reach`. `align(from, k)` aligns the voxel clouds
// from `from` (the k-th probe); `verify(pose, options)` scores a pose as `score` was scored, with
// `options`.
using VerifyWith =
    std::function<VerificationScore(const Matrix4&, const VerificationOptions& options)>;
RivalSearch SearchRival(const Matrix4& result, const VerificationScore& score,
                        const VoxelCloud& source_voxels, double working_voxel,
                        const std::function<RegistrationResult(const Matrix4&, int)>& align,
                        const VerifyWith& verify, RivalReach reach = RivalReach::kNear);

}  // namespace mlsreg::internal
