// Registration options on the wire: the method enum and RegistrationParameters, converted row by
// row from the parameter table (mlsreg/registration/parameters.h) through the proto descriptor.
#pragma once

#include <string_view>

#include "absl/status/statusor.h"
#include "mlsreg/registration/options.h"
#include "mlsreg/v1/mlsreg.pb.h"

namespace mlsreg::wire {

std::string_view MethodName(v1::Method method);  // "mls-sicp", ...; "" for unknown values
absl::StatusOr<Method> MethodFromProto(v1::Method method);  // UNSPECIFIED -> the default
v1::Method MethodToProto(Method method);

// Library defaults overridden by every set field; validated, errors naming the wire field
// ("parameters.mls_radius_d must be in (0, 100]").
absl::StatusOr<RegistrationOptions> OptionsFromProto(v1::Method method,
                                                     const v1::RegistrationParameters& p);
// Every field set explicitly (so a request is reproducible whatever the server's defaults).
void OptionsToProto(const RegistrationOptions& options, v1::Method* method,
                    v1::RegistrationParameters* p);

}  // namespace mlsreg::wire
