// How absl::Status becomes a Python exception: bad input (INVALID_ARGUMENT, OUT_OF_RANGE,
// FAILED_PRECONDITION) is ValueError, NOT_FOUND is LookupError, everything else mlsreg.Error
// (a RuntimeError carrying the status code's name in `.code`). The message is the library's.
#pragma once

#include <stdexcept>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace mlsreg::python {

class StatusError : public std::runtime_error {
 public:
  explicit StatusError(absl::Status status)
      : std::runtime_error(std::string(status.message())), status_(std::move(status)) {}
  const absl::Status& status() const { return status_; }

 private:
  absl::Status status_;
};

inline void ThrowIfError(const absl::Status& status) {
  if (!status.ok()) throw StatusError(status);
}

template <class T>
T ValueOrThrow(absl::StatusOr<T> value) {
  if (!value.ok()) throw StatusError(value.status());
  return *std::move(value);
}

}  // namespace mlsreg::python
