// `mlsreg register --plot out.png`: the convergence of one registration as a picture: RMSE/d per
// iteration (and against ground truth when known), matched and rejected correspondences, the
// stages of method auto shaded. Drawn by python3-matplotlib (cli/plot_convergence.py).
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "absl/status/status.h"
#include "mlsreg/core/point_cloud.h"
#include "mlsreg/registration/result.h"

namespace mlsreg::cli {

// The data the script draws, as JSON text: per iteration its stage, RMSE/d, counts, and with
// `truth` the ground-truth RMSE/d of the iteration's transform over `source`.
std::string ConvergencePlotData(std::string_view method, const RegistrationResult& result,
                                const PointCloud& source, const std::optional<Matrix4>& truth);

// Checked before the registration runs: the extension names a format matplotlib writes (.png,
// .pdf, .svg, .jpg, .jpeg) and the path can be written (cloud_files.h's CheckWritable).
// InvalidArgument naming --plot.
absl::Status CheckPlotPath(const std::string& path);

absl::Status WriteConvergencePlot(const std::string& path, std::string_view method,
                                  const RegistrationResult& result, const PointCloud& source,
                                  const std::optional<Matrix4>& truth);

}  // namespace mlsreg::cli
