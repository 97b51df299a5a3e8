// Method: the registration methods (the paper's MLS-SICP and its comparators), their names and
// what each needs of the target.
#pragma once

#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace mlsreg {

enum class Method {
  kCpSicp,   // Sparse ICP with closest-point correspondences (paper: CP-SICP)
  kMlsSicp,  // Sparse ICP with MLS correspondences (paper: MLS-SICP)
  // The target first projected onto its own MLS surface (de-noised; counted as preprocessing),
  // then CP-SICP (paper: ST-SICP).
  kStSicp,
  // CP-SICP without filtering until it converges, then MLS-SICP from there (paper:
  // CP-SICP+MLS-SICP). max_iterations applies to each phase.
  kCpThenMlsSicp,
  // Generalized ICP, plane-to-plane (Segal et al. 2009; paper: G-ICP). Uses `gicp`, not the
  // Sparse ICP, MLS or filter parameters.
  kGicp,
  // Fast Global Registration with FPFH features (Zhou et al. 2016; paper: FGR). Global: ignores
  // the initial transform. Uses `fgr`.
  kFgr,
  // Reverse calibration with bilinear (RC-BL) or Phong (RC-P) interpolation in the target's depth
  // image, inside Sparse ICP. The target must carry pinhole intrinsics (organised scan).
  kRcBl,
  kRcP,
};
std::string_view MethodName(Method method);  // "cp-sicp", "mls-sicp", "st-sicp", ...
absl::StatusOr<Method> ParseMethod(std::string_view name);
std::vector<Method> AllMethods();
// Whether the method needs an organised target (pinhole intrinsics, a depth image).
bool NeedsOrganisedTarget(Method method);
// FAILED_PRECONDITION naming the method, for a target without intrinsics.
absl::Status OrganisedTargetRequired(Method method);

// Every length below is in units of the target's sampling distance d (paper Eq. 11).

}  // namespace mlsreg
