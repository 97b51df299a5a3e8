#include "cli/convergence_plot.h"

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "cli/cloud_files.h"
#include "cli/embedded_scripts.h"
#include "cli/python_script.h"
#include "mlsreg/evaluation/metrics.h"

namespace mlsreg::cli {

std::string ConvergencePlotData(std::string_view method, const RegistrationResult& result,
                                const PointCloud& source, const std::optional<Matrix4>& truth) {
  nlohmann::json data;
  data["title"] = absl::StrFormat("%s: %s after %d iterations, d = %.4g", std::string(method),
                                  std::string(TerminationName(result.termination)),
                                  result.iterations, result.sampling_distance);
  for (const char* key : {"iteration", "stage", "candidate", "rmse_d", "matched", "rejected_normal",
                          "rejected_curvature", "rejected_distance", "invalid"}) {
    data[key] = nlohmann::json::array();
  }
  data["gt_rmse_d"] = truth ? nlohmann::json::array() : nlohmann::json(nullptr);
  for (const IterationReport& r : result.trace) {
    data["iteration"].push_back(r.iteration);
    data["stage"].push_back(std::string(StageName(r.stage)));
    data["candidate"].push_back(r.candidate);
    data["rmse_d"].push_back(r.rmse_d);
    data["matched"].push_back(r.counts.matched);
    data["rejected_normal"].push_back(r.counts.rejected_normal);
    data["rejected_curvature"].push_back(r.counts.rejected_curvature);
    data["rejected_distance"].push_back(r.counts.rejected_distance);
    data["invalid"].push_back(r.counts.invalid);
    if (truth) {
      data["gt_rmse_d"].push_back(
          EvaluatePose(source.points, r.transform, *truth, result.sampling_distance).rmse_d);
    }
  }
  return data.dump();
}

absl::Status CheckPlotPath(const std::string& path) {
  static constexpr std::string_view kExtensions[] = {".png", ".pdf", ".svg", ".jpg", ".jpeg"};
  const std::string extension =
      absl::AsciiStrToLower(std::filesystem::path(path).extension().string());
  if (std::find(std::begin(kExtensions), std::end(kExtensions), extension) ==
      std::end(kExtensions)) {
    return absl::InvalidArgumentError(
        absl::StrCat("--plot: '", path,
                     "' does not end in .png, .pdf, .svg, .jpg or .jpeg (the picture's format)"));
  }
  return CheckWritable("--plot", path);
}

absl::Status WriteConvergencePlot(const std::string& path, std::string_view method,
                                  const RegistrationResult& result, const PointCloud& source,
                                  const std::optional<Matrix4>& truth) {
  if (result.trace.empty()) {
    return absl::FailedPreconditionError("--plot: the registration has no iterations to draw");
  }
  return RunPythonScript("--plot", kPlotConvergenceScript,
                         ConvergencePlotData(method, result, source, truth), {path});
}

}  // namespace mlsreg::cli
