// Evaluation: runs registration methods over a manifest with ground truth, under the seeded
// initial-pose perturbation protocol, and scores every run (paper section 5.3).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "mlsreg/evaluation/metrics.h"
#include "mlsreg/io/manifest.h"
#include "mlsreg/registration/registration.h"

namespace mlsreg {

// The start pose of problem i is P_i * B_i, where B_i is the manifest's init (or, without one,
// its ground truth) and P_i a rotation of exactly angle_deg about a random axis through the
// centroid of the source under B_i, followed by a translation of exactly translation_d * d in a
// random direction. P_i is seeded by (seed, i), so every method starts from the same pose.
//
// Registration from any start uses two variants: with uniform_rotation the rotation is drawn
// uniformly on SO(3) (any angle; angle_deg is ignored), and with translation_max_d >
// translation_d the translation's length is drawn uniformly in [translation_d,
// translation_max_d].
struct PerturbationProtocol {
  double angle_deg = 0.0;
  double translation_d = 0.0;
  std::uint64_t seed = 1;
  bool uniform_rotation = false;
  double translation_max_d = 0.0;
};

// The start pose of the evaluation protocol, the one place it is written (`mlsreg register
// --perturb-*` and `mlsreg eval` both call it): `initial` followed by a random rotation of
// angle_deg about the source's centroid as `initial` places it and a random translation of
// translation_d * d. Problem `index` of a run draws from seed * 1000003 + index, so `register`
// with a seed starts where problem 0 of `eval` with that seed does. No perturbation (both zero)
// returns `initial`.
Matrix4 PerturbedStart(const PointCloud& source, const Matrix4& initial, double d,
                       const PerturbationProtocol& protocol, std::size_t index = 0);

struct EvaluationOptions {
  std::vector<Method> methods = {Method::kMlsSicp};
  RegistrationOptions registration;  // method is overwritten per run
  PerturbationProtocol perturbation;
  int jobs = 1;     // registrations run in parallel
  int threads = 1;  // threads inside each registration and target build (ExecutionOptions)
  // The indices of the manifest's problems to run (a shard, evaluation/shard.h), ascending;
  // empty: all. A problem keeps its index, and so its perturbed start, in any subset.
  std::vector<std::size_t> problems;
};

struct ProblemOutcome {
  std::size_t problem_index = 0;
  Method method = Method::kMlsSicp;
  absl::Status status;  // load or registration failure; the fields below are then unset
  Matrix4 initial = Matrix4::Identity();
  RegistrationResult result;
  PoseError initial_error;            // of the start pose, against ground truth
  PoseError error;                    // of the result, against ground truth
  std::vector<double> trace_error_d;  // RMSE/d against ground truth after each iteration
  double target_build_seconds = 0.0;
};

// Runs every (problem, method) pair (of options.problems when given); `on_done` (may be empty)
// is called from worker threads, serialised, after each run. Outcomes come back ordered by
// problem, then by method. Fails for a manifest problem without ground truth and for a problem
// index out of range.
absl::StatusOr<std::vector<ProblemOutcome>> RunEvaluation(
    const Manifest& manifest, const EvaluationOptions& options,
    const std::function<void(const ProblemOutcome&, std::size_t done, std::size_t total)>& on_done =
        {});

}  // namespace mlsreg
