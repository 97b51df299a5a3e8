// The method table: one row per registration method.
#include <array>

#include "absl/strings/str_cat.h"
#include "method_runners.h"
#include "mlsreg/registration/method.h"

namespace mlsreg {
namespace {

using namespace internal;

constexpr unsigned kSicpMethod =
    kCommonParameters | kSparseIcpParameters | kFilterParameters;  // any Sparse ICP method

const std::array<MethodSpec, 9> kMethods = {{
    {Method::kAuto, "auto", "AUTO",
     "MLS-SICP from the start, else from global candidates, verified (the default)",
     TargetRequirement::kAnyCloud, kSicpMethod | kMlsParameters | kAutoParameters, &MakeMlsFinder,
     &RunAuto},
    {Method::kCpSicp, "cp-sicp", "CP_SICP", "Sparse ICP with closest-point correspondences",
     TargetRequirement::kAnyCloud, kSicpMethod, &MakeClosestPointFinder, &RunSparseIcp},
    {Method::kMlsSicp, "mls-sicp", "MLS_SICP", "Sparse ICP with MLS correspondences",
     TargetRequirement::kAnyCloud, kSicpMethod | kMlsParameters, &MakeMlsFinder, &RunSparseIcp},
    {Method::kStSicp, "st-sicp", "ST_SICP",
     "the target smoothed onto its own MLS surface, then CP-SICP", TargetRequirement::kAnyCloud,
     kSicpMethod | kMlsParameters, &MakeClosestPointFinder, &RunSmoothedTargetSicp},
    {Method::kCpThenMlsSicp, "cp-sicp+mls-sicp", "CP_SICP_THEN_MLS_SICP",
     "unfiltered CP-SICP to convergence, then MLS-SICP", TargetRequirement::kAnyCloud,
     kSicpMethod | kMlsParameters, &MakeMlsFinder, &RunCpThenMlsSicp},
    {Method::kGicp, "g-icp", "G_ICP", "Generalized ICP, plane-to-plane",
     TargetRequirement::kAnyCloud, kCommonParameters | kGicpParameters, nullptr,
     &RunGeneralizedIcp},
    {Method::kFgr, "fgr", "FGR", "Fast Global Registration with FPFH (ignores the start pose)",
     TargetRequirement::kAnyCloud, kCommonParameters | kFgrParameters, nullptr,
     &RunFastGlobalRegistration, StartUse::kIgnores},
    {Method::kRcBl, "rc-bl", "RC_BL", "reverse calibration, bilinear (organised target)",
     TargetRequirement::kOrganised, kSicpMethod, &MakeBilinearFinder, &RunSparseIcp},
    {Method::kRcP, "rc-p", "RC_P", "reverse calibration, Phong tessellation (organised target)",
     TargetRequirement::kOrganised, kSicpMethod, &MakePhongFinder, &RunSparseIcp},
}};

}  // namespace

std::span<const MethodSpec> MethodTable() { return kMethods; }

const MethodSpec& SpecOf(Method method) {
  for (const MethodSpec& spec : kMethods) {
    if (spec.method == method) return spec;
  }
  return kMethods[0];  // unreachable for a valid enum value
}

const EnumNames& MethodNames() {
  static const std::array<EnumValueName, kMethods.size()> kValues = [] {
    std::array<EnumValueName, kMethods.size()> values{};
    for (std::size_t i = 0; i < kMethods.size(); ++i) {
      values[i] = {static_cast<int>(kMethods[i].method), kMethods[i].name, kMethods[i].wire_suffix};
    }
    return values;
  }();
  static const EnumNames kNames{"Method", "METHOD_", kValues};
  return kNames;
}

std::string_view MethodName(Method method) {
  return MethodNames().NameOf(static_cast<int>(method));
}

absl::StatusOr<Method> ParseMethod(std::string_view name) {
  absl::StatusOr<int> value = MethodNames().Parse(name, "method");
  if (!value.ok()) return value.status();
  return static_cast<Method>(*value);
}

std::vector<Method> AllMethods() {
  std::vector<Method> methods;
  for (const MethodSpec& spec : kMethods) methods.push_back(spec.method);
  return methods;
}

bool NeedsOrganisedTarget(Method method) {
  return SpecOf(method).target == TargetRequirement::kOrganised;
}

absl::Status OrganisedTargetRequired(Method method) {
  return absl::FailedPreconditionError(
      absl::StrCat("method ", std::string(MethodName(method)),
                   " needs an organised target with pinhole intrinsics (a depth image); this "
                   "target has none (give the target file a .intrinsics sidecar, see "
                   "depth_grid.h)"));
}

}  // namespace mlsreg
