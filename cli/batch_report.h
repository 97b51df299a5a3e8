// `mlsreg batch --report out.html`: one self-contained HTML page about a batch (inline CSS and
// SVG, no scripts, nothing fetched when opened): the summary, the failures first, a table of
// every job, the alpha-recall curve when ground truth is known, and a latency histogram.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "mlsreg/core/transform.h"
#include "mlsreg/evaluation/metrics.h"
#include "mlsreg/registration/verification.h"

namespace mlsreg::cli {

// What one job of a batch came to (a row of the results file).
struct JobOutcome {
  std::string id, target_id, error, request_id, termination;
  Matrix4 transform = Matrix4::Identity();
  std::optional<PoseError> pose_error;
  int iterations = 0, attempts = 0;
  double seconds = 0.0;
  std::optional<bool> verified;  // whether the result verified (any method; unset: not verified)
  // The verification's score (verdict, pose covariance) when the registration ran one.
  std::optional<VerificationScore> verification;
};

struct BatchReportInfo {
  std::string manifest;  // its path
  std::string method;
  std::string server;
  int concurrency = 0;
  double wall_seconds = 0.0;
};

std::string BatchReportHtml(const BatchReportInfo& info, const std::vector<JobOutcome>& jobs);
absl::Status WriteBatchReport(const std::string& path, const BatchReportInfo& info,
                              const std::vector<JobOutcome>& jobs);

}  // namespace mlsreg::cli
