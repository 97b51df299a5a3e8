#include "mlsreg/registration/options.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "mlsreg/registration/parameters.h"

namespace mlsreg {

const EnumNames& CoarsePhaseFiltersNames() {
  static constexpr EnumValueName kValues[] = {
      {static_cast<int>(CoarsePhaseFilters::kAll), "all", "ALL"},
      {static_cast<int>(CoarsePhaseFilters::kNormal), "normal", "NORMAL"},
      {static_cast<int>(CoarsePhaseFilters::kNone), "none", "NONE"},
  };
  static constexpr EnumNames kNames{"CoarsePhaseFilters", "COARSE_PHASE_FILTERS_", kValues};
  return kNames;
}

const EnumNames& FarQueryPolicyNames() {
  static constexpr EnumValueName kValues[] = {
      {static_cast<int>(FarQueryPolicy::kSeedUntilConverged), "seed-until-converged",
       "SEED_UNTIL_CONVERGED"},
      {static_cast<int>(FarQueryPolicy::kSeed), "seed", "SEED"},
      {static_cast<int>(FarQueryPolicy::kDrop), "drop", "DROP"},
  };
  static constexpr EnumNames kNames{"FarQueryPolicy", "FAR_QUERY_POLICY_", kValues};
  return kNames;
}

const EnumNames& MlsProjectionKindNames() {
  static constexpr EnumValueName kValues[] = {
      {static_cast<int>(MlsProjectionKind::kPatchesThenExact), "patches-then-exact",
       "PATCHES_THEN_EXACT"},
      {static_cast<int>(MlsProjectionKind::kPatches), "patches", "PATCHES"},
      {static_cast<int>(MlsProjectionKind::kExact), "exact", "EXACT"},
  };
  static constexpr EnumNames kNames{"MlsProjection", "MLS_PROJECTION_", kValues};
  return kNames;
}

const EnumNames& SicpMetricNames() {
  static constexpr EnumValueName kValues[] = {
      {static_cast<int>(SicpMetric::kPointToPlane), "point-to-plane", "POINT_TO_PLANE"},
      {static_cast<int>(SicpMetric::kPointToPoint), "point-to-point", "POINT_TO_POINT"},
  };
  static constexpr EnumNames kNames{"SicpMetric", "SICP_METRIC_", kValues};
  return kNames;
}

absl::Status ValidateOptions(const RegistrationOptions& options) {
  for (const ParameterSpec& spec : ParameterTable()) {
    if (absl::Status s = spec.Check(spec.get(options), spec.name); !s.ok()) return s;
  }
  for (const auto& [name, metres] : options.absolute_lengths) {
    const ParameterSpec* spec = FindParameter(name);
    if (spec == nullptr || !spec->IsLength()) {
      return absl::InvalidArgumentError(
          absl::StrCat("absolute_lengths: ", name, " is not a length parameter"));
    }
    if (!std::isfinite(metres) || !spec->range.AboveMin(metres)) {
      return absl::InvalidArgumentError(absl::StrCat(name, " = ", metres, " m ", spec->Rule()));
    }
  }
  // The solver's constants (mu, alpha, ...) are not registration parameters but are checked too.
  SparseIcpOptions sicp = options.sicp;
  sicp.length_unit = 1.0;  // derived from sicp_length_unit_d, checked above
  return ValidateSparseIcpOptions(sicp);
}

}  // namespace mlsreg
