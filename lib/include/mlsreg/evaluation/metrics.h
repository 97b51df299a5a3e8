// Accuracy metrics against ground truth (paper section 5.3).
#pragma once

#include <span>
#include <vector>

#include "mlsreg/core/point_cloud.h"
#include "mlsreg/core/transform.h"

namespace mlsreg {

// Paper Eq. 10 without the 1/d factor: sqrt(1/n sum |T_r p - T_g p|^2) over all source points.
double GroundTruthRmse(std::span<const Vec3> source_points, const Matrix4& estimate,
                       const Matrix4& truth);

struct PoseError {
  double rmse_d = 0.0;         // Eq. 10: RMSE in units of the sampling distance d
  bool success = false;        // rmse_d < success_threshold_d (paper: 5 d)
  double rotation_deg = 0.0;   // angle of R_truth^T R_estimate
  double translation_d = 0.0;  // |t_estimate - t_truth| / d
};

PoseError EvaluatePose(std::span<const Vec3> source_points, const Matrix4& estimate,
                       const Matrix4& truth, double sampling_distance,
                       double success_threshold_d = 5.0);

}  // namespace mlsreg
