// Method: the registration methods (the paper's MLS-SICP and its comparators) and the method
// table, one row per method: its name, its wire name, what the target must carry, which
// parameter groups it reads, and the runner that registers with it. Name, parse, list,
// preconditions, dispatch, the wire enum mapping and the CLI help all read the table, so adding
// a method is one row (lib/src/registration/method_table.cc) plus its code.
#pragma once

#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "mlsreg/core/enum_names.h"

namespace mlsreg {

enum class Method {
  // The default: MLS-SICP from the start pose; when its result does not verify against the
  // target's MLS surface, MLS-SICP from global feature candidates, the best verified one kept.
  // Reports every candidate and whether the result verified. Uses `auto` and the MLS-SICP groups.
  kAuto,
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

// What a method needs of the target.
enum class TargetRequirement {
  kAnyCloud,
  kOrganised,  // pinhole intrinsics, so that the target has a depth grid
};

// Groups of registration parameters (RegistrationOptions); a method reads a set of them.
enum ParameterGroup : unsigned {
  kCommonParameters = 1u << 0,  // samples, seed, iterations, convergence, min correspondences
  kSparseIcpParameters = 1u << 1,
  kMlsParameters = 1u << 2,
  kFilterParameters = 1u << 3,
  kGicpParameters = 1u << 4,
  kFgrParameters = 1u << 5,
  kAutoParameters = 1u << 6,
};

class CorrespondenceFinder;
class Target;
struct RegistrationOptions;
struct RegistrationProblem;  // lib/src/registration/method_runners.h
struct RegistrationResult;

// What a method does with the caller's start pose.
enum class StartUse {
  kRefines,  // aligns from it (every ICP method; auto runs its own global stage when it must)
  kIgnores,  // searches globally (FGR): its result may be any alias of the truth
};

struct MethodSpec {
  Method method;
  std::string_view name;         // "mls-sicp": CLI, reports, CSV columns
  std::string_view wire_suffix;  // "MLS_SICP": the wire enum value METHOD_<suffix>
  std::string_view summary;      // one line for help texts
  TargetRequirement target;
  unsigned parameter_groups;  // ParameterGroup bits
  // The correspondence policy of a Sparse ICP method; null for G-ICP and FGR.
  std::unique_ptr<CorrespondenceFinder> (*make_finder)(const Target& target,
                                                       const RegistrationOptions& options);
  absl::StatusOr<RegistrationResult> (*run)(const RegistrationProblem& problem);
  // Sets how far the rival search of the method's verdict reaches (rival_search.h).
  StartUse start_use = StartUse::kRefines;
};

// Every method, in the order of the paper's tables.
std::span<const MethodSpec> MethodTable();
const MethodSpec& SpecOf(Method method);
// The methods' names as an enum table (wire enum "Method").
const EnumNames& MethodNames();

std::string_view MethodName(Method method);  // "cp-sicp", "mls-sicp", "st-sicp", ...
absl::StatusOr<Method> ParseMethod(std::string_view name);
std::vector<Method> AllMethods();
// Whether the method needs an organised target (pinhole intrinsics, a depth image).
bool NeedsOrganisedTarget(Method method);
// FAILED_PRECONDITION naming the method, for a target without intrinsics.
absl::Status OrganisedTargetRequired(Method method);

}  // namespace mlsreg
