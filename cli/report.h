// Human- and machine-readable rendering of registration progress and results.
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "mlsreg/evaluation/metrics.h"
#include "mlsreg/registration/registration.h"

namespace mlsreg::cli {

// One line per ICP iteration, e.g.
// "iter   7  rmse 0.8123 d  matched 1523  rejected normal 12 curvature 301 distance 0  invalid 164
// 0.31 s"
std::string FormatIteration(const IterationReport& report);

// "max_iterations (100 per phase) after 115 iterations in total": the limit holds for each
// phase (MLS-SICP's coarse and fine; each stage of auto), the count is of every iteration run.
// Other terminations: "converged after 15 iterations".
std::string FormatTermination(const RegistrationResult& result, int max_iterations);

// The final summary block (termination, transform, errors against ground truth when known);
// `max_iterations` is the limit the registration ran with.
std::string FormatResult(const RegistrationResult& result, const std::optional<PoseError>& error,
                         int max_iterations);
// One line: the verdict and its evidence.
std::string FormatVerification(const VerificationScore& score);
// "rival: a pose 0.93 away (turned 0.04 deg) explains 97.1 % as large a share of ...: ..." for
// the rival of `result` (scored `score`).
std::string FormatRival(const AutoCandidate& rival, const VerificationScore& score,
                        const Matrix4& result);
nlohmann::json RivalJson(const AutoCandidate& rival);
nlohmann::json VerificationJson(const VerificationScore& score);
// A pose covariance (a verification's, a scan's in `align`), 36 row-major values, or null.
nlohmann::json PoseCovarianceJson(const std::optional<Eigen::Matrix<double, 6, 6>>& covariance);

// Progress of many jobs on stderr: a bar redrawn in place on a terminal, plain lines otherwise.
class ProgressPrinter {
 public:
  ProgressPrinter();  // detects whether stderr is a terminal
  void Update(std::size_t done, std::size_t total, const std::string& line);

 private:
  bool terminal_;
};

nlohmann::json IterationJson(const IterationReport& report);
nlohmann::json ResultJson(std::string_view method, const RegistrationResult& result,
                          const std::optional<PoseError>& error);

}  // namespace mlsreg::cli
