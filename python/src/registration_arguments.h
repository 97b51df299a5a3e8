// Python arguments of a registration -> the library's types, and its results -> Python objects.
// Parameters are keyword arguments named after the parameter table's wire fields (mls_radius_d,
// sicp_p, auto_candidates, ...; the table's dotted names are accepted too), with the table's
// defaults, ranges and messages. None means "auto" for a parameter that allows it.
#pragma once

#include <pybind11/pybind11.h>

#include <string_view>

#include "mlsreg/core/length.h"
#include "mlsreg/core/transform.h"
#include "mlsreg/registration/options.h"
#include "mlsreg/registration/result.h"

namespace mlsreg::python {

namespace py = pybind11;

// `method` by its table name ("auto", "mls-sicp", ...); `params` maps parameter names to values.
RegistrationOptions OptionsFromPython(std::string_view method, const py::dict& params);
// A 4x4 rigid transform (array-like); None is the identity. `field` names it in messages.
Matrix4 TransformFromPython(py::handle object, std::string_view field);

// A length as the CLI takes it: a number is in units of d, a str is ParseLength's text ("20",
// "20d", "5m", "30cm"). ValueError naming `field` otherwise.
GivenLength LengthFromPython(py::handle value, std::string_view field);

// Requires the GIL.
py::dict ReportToPython(const IterationReport& report);
py::dict ResultToPython(const RegistrationResult& result);

}  // namespace mlsreg::python
