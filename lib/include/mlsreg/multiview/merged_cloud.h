// The aligned scans as one cloud: every scan under its pose (MergeScans), and optionally that
// cloud resampled onto the joint MLS surface of all scans (ResampleOnMlsSurface): one point per
// voxel, projected by the paper's Algorithm 1 onto the surface the scans agree on. Overlapping
// scans then no longer lie in layers a residual misalignment apart, and their noise is smoothed
// at the scale the MLS radius rule (geometry/mls_radius.h) chooses from the noise measured on
// the merged cloud, misalignment included.
#pragma once

#include <vector>

#include "absl/status/statusor.h"
#include "mlsreg/core/length.h"
#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/stop_check.h"
#include "mlsreg/core/transform.h"

namespace mlsreg {

// Every scan under its pose, one cloud (normals rotated along when all scans have them).
PointCloud MergeScans(const std::vector<PointCloud>& scans, const std::vector<Matrix4>& poses);

struct SurfaceResampling {
  // One point per occupied voxel of this edge: in (0, 100] d, or in the clouds' units.
  GivenLength spacing{1.0, false};
  // MLS support radius: in [0, 100] d, or in the clouds' units; 0: the automatic radius of the
  // noise estimated on the merged cloud, never below that rule's minimum of 5 d.
  GivenLength radius{0.0, false};
  int threads = 1;
};

struct ResampledCloud {
  PointCloud cloud;            // points on the MLS surface, with its normals
  double radius_d = 0.0;       // the support radius used (units of d)
  double noise_sigma_d = 0.0;  // the noise estimated on the merged cloud (units of d)
  // Voxel samples whose projection failed (too few neighbours, no plane, no convergence) or
  // moved them farther than the radius: left out.
  int dropped = 0;
  double seconds = 0.0;
};

// `merged` is MergeScans' cloud, `d` the scans' sampling distance (AlignResult's). Voxel
// representatives of the merged cloud are projected onto its MLS surface. InvalidArgument for a
// cloud of fewer than 10 points or bad options; CANCELLED when `should_stop` says stop.
absl::StatusOr<ResampledCloud> ResampleOnMlsSurface(const PointCloud& merged, double d,
                                                    const SurfaceResampling& options = {},
                                                    const StopCheck& should_stop = {});

}  // namespace mlsreg
