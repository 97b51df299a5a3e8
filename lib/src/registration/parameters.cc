#include "mlsreg/registration/parameters.h"

#include <charconv>
#include <cmath>
#include <optional>
#include <type_traits>
#include <vector>

#include "absl/strings/str_cat.h"
#include "mlsreg/core/length.h"

namespace mlsreg {
namespace {

// The member of RegistrationOptions at the end of a chain of member pointers.
template <auto... Path>
constexpr auto& Member(RegistrationOptions& o) {
  return (o.*....*Path);
}
template <auto... Path>
constexpr const auto& Member(const RegistrationOptions& o) {
  return (o.*....*Path);
}

template <typename T>
struct IsOptional : std::false_type {};
template <typename T>
struct IsOptional<std::optional<T>> : std::true_type {};

template <typename T>
constexpr ParameterType TypeOf() {
  if constexpr (std::is_enum_v<T>) return ParameterType::kEnum;
  if constexpr (std::is_same_v<T, bool>) return ParameterType::kBool;
  if constexpr (std::is_same_v<T, std::uint64_t>) return ParameterType::kUint64;
  if constexpr (std::is_integral_v<T>) return ParameterType::kInt;
  return ParameterType::kDouble;
}

template <auto... Path>
ParameterValue Get(const RegistrationOptions& o) {
  const auto& v = Member<Path...>(o);
  using T = std::decay_t<decltype(v)>;
  if constexpr (IsOptional<T>::value) {
    return v ? ParameterValue(*v) : ParameterValue(std::monostate{});
  } else if constexpr (std::is_enum_v<T>) {
    return static_cast<std::int64_t>(static_cast<int>(v));
  } else if constexpr (std::is_same_v<T, bool> || std::is_same_v<T, std::uint64_t> ||
                       std::is_same_v<T, double>) {
    return v;
  } else {
    return static_cast<std::int64_t>(v);
  }
}

// Only called with a value that Check accepted (of the row's type and in range).
template <auto... Path>
void Set(RegistrationOptions& o, const ParameterValue& value) {
  auto& v = Member<Path...>(o);
  using T = std::decay_t<decltype(v)>;
  if constexpr (IsOptional<T>::value) {
    if (std::holds_alternative<std::monostate>(value)) {
      v.reset();
    } else {
      v = std::get<double>(value);
    }
  } else if constexpr (std::is_enum_v<T>) {
    v = static_cast<T>(std::get<std::int64_t>(value));
  } else if constexpr (std::is_same_v<T, bool> || std::is_same_v<T, std::uint64_t> ||
                       std::is_same_v<T, double>) {
    v = std::get<T>(value);
  } else {
    v = static_cast<T>(std::get<std::int64_t>(value));
  }
}

// One row: `Path` locates the field, whose type gives the parameter's type.
template <auto... Path>
ParameterSpec Row(std::string_view name, std::string_view flag, std::string_view wire_field,
                  ParameterGroup group, ParameterRange range, std::string_view help,
                  std::string_view note = {}, const EnumNames* enum_names = nullptr) {
  using T = std::decay_t<decltype(Member<Path...>(std::declval<RegistrationOptions&>()))>;
  constexpr bool optional = IsOptional<T>::value;
  using Value = std::conditional_t<optional, double, T>;
  return ParameterSpec{name,  flag,       wire_field, help, group,         TypeOf<Value>(),
                       range, enum_names, optional,   note, &Get<Path...>, &Set<Path...>};
}

template <auto... Path>
ParameterSpec EnumRow(std::string_view name, std::string_view flag, std::string_view wire_field,
                      ParameterGroup group, const EnumNames& names, std::string_view help) {
  return Row<Path...>(name, flag, wire_field, group, {}, help, {}, &names);
}

using O = RegistrationOptions;
constexpr ParameterRange kAtLeast(double min) { return {min}; }
constexpr ParameterRange kClosed(double min, double max) { return {min, max}; }
constexpr ParameterRange kOpenClosed(double min, double max) { return {min, max, true}; }
constexpr ParameterRange kAny{};

std::vector<ParameterSpec> MakeTable() {
  constexpr ParameterGroup common = kCommonParameters, sicp = kSparseIcpParameters,
                           mls = kMlsParameters, filter = kFilterParameters, gicp = kGicpParameters,
                           fgr = kFgrParameters, automatic = kAutoParameters;
  return {
      Row<&O::num_samples>("num_samples", "samples", "num_samples", common,
                           kClosed(3, kMaxNumSamples), "random source samples"),
      Row<&O::seed>("seed", "seed", "seed", common, kAny, "subsampling seed"),
      Row<&O::max_iterations>("max_iterations", "max-iterations", "max_iterations", common,
                              kClosed(1, 100'000), "ICP iterations (per phase)"),
      Row<&O::convergence_d>("convergence_d", "convergence", "convergence_d", common,
                             kClosed(0, 100),
                             "stop when no sample moves more than this (units of d)"),
      Row<&O::coarse_convergence_d>(
          "coarse_convergence_d", "coarse-convergence", "coarse_convergence_d", mls,
          kClosed(0, 100), "the same for the coarse phase of MLS far-query seeding (units of d)"),
      Row<&O::stall_d>("stall_d", "stall", "stall_d", sicp, kClosed(0, 100),
                       "also stop when the last 8 poses stay within this (units of d)",
                       "(0 disables)"),
      Row<&O::tangential_damping>(
          "tangential_damping", "tangential-damping", "tangential_damping", sicp, kClosed(0, 1000),
          "point-to-plane with MLS/RC partners: weight damping sliding along the surface"),
      Row<&O::min_correspondences>("min_correspondences", "min-correspondences",
                                   "min_correspondences", common, kClosed(3, kMaxNumSamples),
                                   "fewer accepted correspondences end the registration"),
      Row<&O::sicp_unit_per_residual>(
          "sicp_unit_per_residual", "sicp-unit-per-residual", "sicp_unit_per_residual", sicp,
          kClosed(0, 1000),
          "far from the solution the Sparse ICP unit grows to this many median residuals",
          "(0 keeps it fixed)"),
      Row<&O::stall_noise_fraction>(
          "stall_noise_fraction", "stall-noise", "stall_noise_fraction", sicp, kClosed(0, 10),
          "also stop when the last 8 poses stay within this fraction of the estimated noise",
          "(0 disables)"),
      Row<&O::stall_standard_errors>(
          "stall_standard_errors", "stall-standard-errors", "stall_standard_errors", sicp,
          kClosed(0, 100),
          "also stop when the last 6 poses stay within this many standard errors rmse/sqrt(n)",
          "(0 disables)"),
      Row<&O::sicp_length_unit_d>("sicp_length_unit_d", "sicp-unit", "sicp_length_unit_d", sicp,
                                  kOpenClosed(0, 1e6), "Sparse ICP length unit (units of d)"),
      Row<&O::sicp, &SparseIcpOptions::p>("sicp.p", "sicp-p", "sicp_p", sicp, kOpenClosed(0, 1),
                                          "Sparse ICP lp exponent"),
      Row<&O::sicp, &SparseIcpOptions::max_outer>("sicp.max_outer", "sicp-outer", "sicp_max_outer",
                                                  sicp, kClosed(1, 10'000),
                                                  "ADMM iterations per ICP iteration"),
      EnumRow<&O::sicp, &SparseIcpOptions::metric>("sicp.metric", "sicp-metric", "sicp_metric",
                                                   sicp, SicpMetricNames(), "Sparse ICP residual"),
      Row<&O::mls, &MlsParams::radius_d>("mls.radius_d", "mls-radius", "mls_radius_d", mls,
                                         kOpenClosed(0, 100), "MLS support radius r (units of d)"),
      Row<&O::mls, &MlsParams::polynomial_degree>("mls.polynomial_degree", "mls-degree",
                                                  "mls_polynomial_degree", mls, kClosed(0, 3),
                                                  "MLS polynomial degree"),
      Row<&O::mls, &MlsParams::max_iterations>("mls.max_iterations", "mls-max-iterations",
                                               "mls_max_iterations", mls, kClosed(1, 1000),
                                               "iterations of one MLS projection"),
      Row<&O::mls, &MlsParams::warm_start>("mls.warm_start", "no-warm-start", "mls_warm_start", mls,
                                           kAny,
                                           "start every MLS projection from the query itself"),
      EnumRow<&O::mls, &MlsParams::far_queries>(
          "mls.far_queries", "mls-far-queries", "mls_far_queries", mls, FarQueryPolicyNames(),
          "queries with < 3 target samples within r: seed them from the nearest sample until "
          "converged, then drop them; always seed; or drop (paper Alg. 1)"),
      EnumRow<&O::mls, &MlsParams::projection>(
          "mls.projection", "mls-projection", "mls_projection", mls, MlsProjectionKindNames(),
          "MLS projection: the target's precomputed patches until first converged, then the "
          "exact Algorithm 1; patches only (fastest); or exact only (the paper's reference)"),
      Row<&O::filter, &FilterParams::min_normal_dot>("filter.min_normal_dot", "tau-n",
                                                     "min_normal_dot", filter, kClosed(-1, 1),
                                                     "normal filter: min <n1,n2>", "(-1 disables)"),
      Row<&O::filter, &FilterParams::min_curvature_ratio>(
          "filter.min_curvature_ratio", "tau-h", "min_curvature_ratio", filter, kClosed(0, 1),
          "curvature filter: min H1/H2 ratio", "(0 disables)"),
      Row<&O::filter, &FilterParams::max_distance_d>(
          "filter.max_distance_d", "max-distance", "max_distance_d", filter, kAtLeast(0),
          "reject correspondences farther than this (units of d)", "(0 disables)"),
      EnumRow<&O::filter, &FilterParams::coarse_phase>(
          "filter.coarse_phase", "coarse-filters", "coarse_phase_filters", filter,
          CoarsePhaseFiltersNames(),
          "filters of the MLS coarse phase: tau-n and tau-h, tau-n only, or none"),
      Row<&O::gicp, &GicpParams::covariance_neighbors>(
          "gicp.covariance_neighbors", "gicp-neighbors", "gicp_covariance_neighbors", gicp,
          kClosed(3, 64), "G-ICP: neighbours per covariance"),
      Row<&O::gicp, &GicpParams::epsilon>("gicp.epsilon", "gicp-epsilon", "gicp_epsilon", gicp,
                                          kOpenClosed(0, 1), "G-ICP: plane-to-plane epsilon"),
      Row<&O::gicp, &GicpParams::max_distance_d>("gicp.max_distance_d", "gicp-max-distance",
                                                 "gicp_max_distance_d", gicp, kOpenClosed(0, 1e6),
                                                 "G-ICP: max correspondence distance (units of d)"),
      Row<&O::fgr, &FgrParams::feature_radius_d>(
          "fgr.feature_radius_d", "fgr-radius", "fgr_feature_radius_d", fgr,
          kOpenClosed(0, kMaxFgrFeatureRadiusD), "FGR: FPFH radius (units of d)"),
      Row<&O::fgr, &FgrParams::samples>(
          "fgr.samples", "fgr-samples", "fgr_samples", fgr, kClosed(10, kMaxFgrSamples),
          "FGR: at most this many voxel samples per cloud get features"),
      Row<&O::automatic, &AutoParams::candidates>(
          "auto.candidates", "auto-candidates", "auto_candidates", automatic, kClosed(1, 32),
          "auto: global candidate poses refined when the start does not verify"),
      Row<&O::automatic, &AutoParams::accept_fraction>(
          "auto.accept_fraction", "auto-accept", "auto_accept_fraction", automatic, kClosed(0, 1),
          "auto: keep the start's verified result without a global stage when it lays this "
          "share of the source over the target (of the share the target's sensor could see, "
          "when its sampling shows one)"),
      Row<&O::automatic, &AutoParams::candidate_iterations>(
          "auto.candidate_iterations", "auto-candidate-iterations", "auto_candidate_iterations",
          automatic, kClosed(1, 1000),
          "auto: iterations of each candidate's voxel-cloud alignment"),
      Row<&O::automatic, &AutoParams::finish>(
          "auto.finish", "no-auto-finish", "auto_finish", automatic, kAny,
          "auto: keep the refinement's pose; do not polish a verified result over every source "
          "point with the finish the noise chooses"),
      Row<&O::verify>("verify", "no-verify", "verify", common, kAny,
                      "skip verifying the result against the target (every method verifies)"),
  };
}

// The whole of `text` as a number of type T, into `value`; false when it is not one.
template <typename T>
bool ParseNumber(std::string_view text, ParameterValue& value) {
  T v;
  const char* end = text.data() + text.size();
  auto [p, ec] = std::from_chars(text.data(), end, v);
  if (ec != std::errc() || p != end) return false;
  value = v;
  return true;
}

// Bounds print as integers where they are ("1000000", not "1e+06").
std::string Bound(double v) {
  if (std::abs(v) < 1e15 && v == std::floor(v)) return absl::StrCat(static_cast<std::int64_t>(v));
  return absl::StrCat(v);
}

}  // namespace

std::span<const ParameterSpec> ParameterTable() {
  static const std::vector<ParameterSpec> kTable = MakeTable();
  return kTable;
}

const ParameterSpec* FindParameter(std::string_view name) {
  for (const ParameterSpec& spec : ParameterTable()) {
    if (spec.name == name) return &spec;
  }
  return nullptr;
}

std::string ParameterSpec::Rule() const {
  std::string rule;
  if (type == ParameterType::kEnum) {
    rule = "must be one of " + enum_names->Choices(", ");
  } else if (type == ParameterType::kBool) {
    rule = "must be true or false";
  } else if (type == ParameterType::kUint64) {  // the range of its type: a seed
    rule = "must be an integer from 0 to 18446744073709551615";
  } else if (std::isinf(range.min) && std::isinf(range.max)) {
    rule = type == ParameterType::kInt ? "must be an integer" : "must be a finite number";
  } else if (std::isinf(range.max)) {
    rule = absl::StrCat("must be ", range.min_open ? "> " : ">= ", Bound(range.min));
  } else {
    rule = absl::StrCat("must be in ", range.min_open ? "(" : "[", Bound(range.min), ", ",
                        Bound(range.max), "]");
  }
  if (auto_allowed) rule += " or auto";
  if (!note.empty()) rule.append(" ").append(note);
  return rule;
}

absl::Status ParameterSpec::Check(const ParameterValue& value, std::string_view field) const {
  const auto bad = [&] { return absl::InvalidArgumentError(std::string(field) + " " + Rule()); };
  if (std::holds_alternative<std::monostate>(value)) {
    return auto_allowed ? absl::OkStatus() : bad();
  }
  switch (type) {
    case ParameterType::kBool:
      return std::holds_alternative<bool>(value) ? absl::OkStatus() : bad();
    case ParameterType::kEnum: {
      const std::int64_t* v = std::get_if<std::int64_t>(&value);
      if (v == nullptr || enum_names->NameOf(static_cast<int>(*v)) == "unknown") return bad();
      return absl::OkStatus();
    }
    case ParameterType::kUint64:
      return std::holds_alternative<std::uint64_t>(value) ? absl::OkStatus() : bad();
    case ParameterType::kInt:
    case ParameterType::kDouble: {
      double v;
      if (const std::int64_t* i = std::get_if<std::int64_t>(&value);
          i != nullptr && type == ParameterType::kInt) {
        v = static_cast<double>(*i);
      } else if (const double* d = std::get_if<double>(&value);
                 d != nullptr && type == ParameterType::kDouble) {
        v = *d;
      } else {
        return bad();
      }
      if (!std::isfinite(v) || !range.AboveMin(v) || !(v <= range.max)) return bad();
      return absl::OkStatus();
    }
  }
  return bad();
}

std::string ParameterSpec::Format(const ParameterValue& value) const {
  if (type == ParameterType::kEnum) {
    return std::string(enum_names->NameOf(static_cast<int>(std::get<std::int64_t>(value))));
  }
  return std::visit(
      [](const auto& v) -> std::string {
        if constexpr (std::is_same_v<std::decay_t<decltype(v)>, std::monostate>) {
          return "auto";
        } else if constexpr (std::is_same_v<std::decay_t<decltype(v)>, bool>) {
          return v ? "true" : "false";
        } else {
          return absl::StrCat(v);
        }
      },
      value);
}

absl::StatusOr<ParameterValue> ParameterSpec::Parse(std::string_view text,
                                                    std::string_view field) const {
  const auto bad = [&] {
    return absl::InvalidArgumentError(std::string(field) + ": '" + std::string(text) +
                                      "' is not valid: " + Rule());
  };
  ParameterValue value;
  if (auto_allowed && text == "auto") return ParameterValue(std::monostate{});
  switch (type) {
    case ParameterType::kEnum: {
      absl::StatusOr<int> v = enum_names->Parse(text, field);
      if (!v.ok()) return v.status();
      value = static_cast<std::int64_t>(*v);
      break;
    }
    case ParameterType::kBool:
      if (text == "true" || text == "1") {
        value = true;
      } else if (text == "false" || text == "0") {
        value = false;
      } else {
        return bad();
      }
      break;
    case ParameterType::kInt:
      if (!ParseNumber<std::int64_t>(text, value)) return bad();
      break;
    case ParameterType::kUint64:
      if (!ParseNumber<std::uint64_t>(text, value)) return bad();
      break;
    case ParameterType::kDouble:
      if (!ParseNumber<double>(text, value)) return bad();
      break;
  }
  if (absl::Status s = Check(value, field); !s.ok()) return s;
  return value;
}

absl::Status SetParameterFromText(RegistrationOptions& options, const ParameterSpec& spec,
                                  std::string_view text, std::string_view field) {
  ParameterValue value;
  // A length with a unit ("5m", "12d"); anything else ("auto", a plain number) is the row's.
  const absl::StatusOr<GivenLength> length =
      spec.IsLength() ? ParseLength(text, field) : absl::StatusOr<GivenLength>();
  if (length.ok() && length->absolute) {
    if (!spec.range.AboveMin(length->value)) {
      return absl::InvalidArgumentError(absl::StrCat(
          std::string(field), ": '", std::string(text), "' is not valid: ", spec.Rule(),
          " in units of d, or a length in m, cm or mm ",
          spec.range.min_open ? "(> " : "(>= ", Bound(spec.range.min), ")"));
    }
    options.absolute_lengths.insert_or_assign(std::string(spec.name), length->value);
    return absl::OkStatus();
  }
  if (length.ok()) {
    value = length->value;
    if (absl::Status s = spec.Check(value, field); !s.ok()) return s;
  } else {
    absl::StatusOr<ParameterValue> parsed = spec.Parse(text, field);
    if (!parsed.ok()) return parsed.status();
    value = *std::move(parsed);
  }
  spec.set(options, value);
  if (auto it = options.absolute_lengths.find(spec.name); it != options.absolute_lengths.end()) {
    options.absolute_lengths.erase(it);
  }
  return absl::OkStatus();
}

absl::StatusOr<RegistrationOptions> ResolveLengths(const RegistrationOptions& options, double d) {
  RegistrationOptions resolved = options;
  resolved.absolute_lengths.clear();
  for (const auto& [name, metres] : options.absolute_lengths) {
    const ParameterSpec* spec = FindParameter(name);
    if (spec == nullptr || !spec->IsLength()) {
      return absl::InvalidArgumentError(
          absl::StrCat("absolute_lengths: ", name, " is not a length parameter"));
    }
    const double in_d = metres / d;
    if (absl::Status s = spec->Check(in_d, name); !s.ok()) {
      return absl::InvalidArgumentError(absl::StrCat(name, " = ", metres, " m is ", in_d,
                                                     " d on this target (d = ", d,
                                                     " m): ", spec->Rule()));
    }
    spec->set(resolved, in_d);
  }
  return resolved;
}

}  // namespace mlsreg
