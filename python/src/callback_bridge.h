// CallbackBridge: a Python callback called from library work that runs without the GIL (a
// registration's iterations, AlignScans' edges). Each call takes the GIL; the callback returning
// False (or raising, or Ctrl-C) stops the work at its next poll, and the exception is raised
// again once it has returned.
#pragma once

#include <pybind11/pybind11.h>

#include <atomic>
#include <memory>

#include "mlsreg/registration/result.h"
#include "python/src/registration_arguments.h"

namespace mlsreg::python {

class CallbackBridge {
 public:
  explicit CallbackBridge(py::object callback) : callback_(std::move(callback)) {}
  ~CallbackBridge() {
    if (error_) {  // not re-raised (an error elsewhere came first): drop it with the GIL
      py::gil_scoped_acquire gil;
      error_.reset();
    }
  }

  // Called without the GIL (from any thread, one at a time): takes the GIL and calls
  // `call(callback)`, which passes the callback its arguments and returns its answer.
  template <class Call>
  void Invoke(Call call) {
    if (callback_.is_none() || stop_.load()) return;
    py::gil_scoped_acquire gil;
    try {
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
      py::object answer = call(callback_);
      if (!answer.is_none() && !py::bool_(answer)) stop_.store(true);
    } catch (py::error_already_set& e) {
      error_ = std::make_unique<py::error_already_set>(std::move(e));
      stop_.store(true);
    }
  }

  // A registration's per-iteration callback.
  void OnIteration(const IterationReport& report) {
    Invoke([&](const py::object& callback) { return callback(ReportToPython(report)); });
  }
  bool ShouldStop() const { return stop_.load(); }
  const std::atomic<bool>* stop_flag() const { return &stop_; }

  // With the GIL: raises what the callback raised, if anything.
  void RaiseIfFailed() {
    if (error_) {
      py::error_already_set e = std::move(*error_);
      error_.reset();
      throw e;
    }
  }

  RegistrationCallbacks Callbacks() {
    RegistrationCallbacks callbacks;
    callbacks.on_iteration = [this](const IterationReport& r) { OnIteration(r); };
    callbacks.should_stop = [this] { return ShouldStop(); };
    return callbacks;
  }

 private:
  py::object callback_;
  std::atomic<bool> stop_{false};
  std::unique_ptr<py::error_already_set> error_;
};

}  // namespace mlsreg::python
