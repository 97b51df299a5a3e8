// Register: validates the problem, checks the method's preconditions, and runs the method's row
// of the method table.
#include "mlsreg/registration/registration.h"

#include "absl/strings/str_cat.h"
#include "method_runners.h"

namespace mlsreg {

const EnumNames& TerminationNames() {
  static constexpr EnumValueName kValues[] = {
      {static_cast<int>(Termination::kConverged), "converged", "CONVERGED"},
      {static_cast<int>(Termination::kMaxIterations), "max_iterations", "MAX_ITERATIONS"},
      {static_cast<int>(Termination::kCancelled), "cancelled", "CANCELLED"},
      {static_cast<int>(Termination::kTooFewCorrespondences), "too_few_correspondences",
       "TOO_FEW_CORRESPONDENCES"},
  };
  static constexpr EnumNames kNames{"Termination", "TERMINATION_", kValues};
  return kNames;
}

std::string_view TerminationName(Termination termination) {
  return NameOf(TerminationNames(), termination);
}

absl::StatusOr<RegistrationResult> Register(const Target& target, const PointCloud& source,
                                            const Matrix4& initial,
                                            const RegistrationOptions& options,
                                            const RegistrationCallbacks& callbacks) {
  const internal::Clock::time_point start = internal::Clock::now();
  if (absl::Status s = ValidateOptions(options); !s.ok()) return s;
  if (absl::Status s = ValidatePointCloud(source, 3); !s.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("source: ", s.message()));
  }
  if (absl::Status s = CheckCoordinateRange(source); !s.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("source: ", s.message()));
  }
  if (absl::Status s = CheckRigid(initial, "initial_transform"); !s.ok()) return s;
  const MethodSpec& method = SpecOf(options.method);
  if (method.target == TargetRequirement::kOrganised && !target.grid()) {
    return OrganisedTargetRequired(options.method);
  }

  const RegistrationProblem problem{&target, &source, initial, &options, &callbacks, start};
  absl::StatusOr<RegistrationResult> result = method.run(problem);
  if (result.ok()) result->timings.total = internal::Seconds(start);
  return result;
}

}  // namespace mlsreg
