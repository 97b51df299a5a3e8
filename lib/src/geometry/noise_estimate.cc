#include "mlsreg/geometry/noise_estimate.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "mlsreg/core/parallel_for.h"
#include "mlsreg/geometry/height_field_fit.h"
#include "mlsreg/geometry/weighted_covariance.h"
#include "mlsreg/geometry/wendland.h"

namespace mlsreg {
namespace {

// The fit radius must exceed the noise's thickness several times for the neighbourhood's PCA
// plane to be the surface's.
constexpr double kRadiusPerSigma = 5.0;
constexpr double kGatherFactor = 1.5;

// The noise standard deviation at one probe (absolute units), or a negative value when its
// neighbourhood cannot be fitted.
double ProbeSigma(const std::vector<Vec3>& points, const KdTree& tree, const Vec3& at,
                  double radius, RadiusNeighbors& neighbors) {
  // Neighbours are gathered beyond the radius, because the weights below use the distance along
  // the surface: the probe itself sits off the surface by its own noise, and weighting by the 3D
  // distance from it would favour neighbours displaced the same way, hiding part of the noise.
  tree.Radius(at, kGatherFactor * radius, neighbors);
  WeightedCovariance covariance(at);
  for (const auto& [index, distance_squared] : neighbors) {
    covariance.Add(points[index],
                   WendlandWeight(std::sqrt(distance_squared), kGatherFactor * radius));
  }
  LocalFrame frame;
  if (covariance.count() < 12 || !covariance.Finalize(frame)) return -1.0;
  const auto tangential_weight = [&](const Vec3& q) {
    const Vec3 offset = q - frame.mean;
    const double u = offset.dot(frame.tangent_u), v = offset.dot(frame.tangent_v);
    return WendlandWeight(std::sqrt(u * u + v * v), radius);
  };
  HeightFieldFit fit(2);
  const double inv_r = 1.0 / radius;
  double sum_w = 0.0, sum_w2 = 0.0;
  for (const auto& [index, distance_squared] : neighbors) {
    const double w = tangential_weight(points[index]);
    if (w <= 0.0) continue;
    const Vec3 local = (points[index] - frame.mean) * inv_r;
    fit.Add(local.dot(frame.tangent_u), local.dot(frame.tangent_v), local.dot(frame.normal), w);
    sum_w += w;
    sum_w2 += w * w;
  }
  HeightField height;
  if (!(sum_w > 0.0) || !fit.Finalize(height)) return -1.0;
  const double effective = sum_w * sum_w / sum_w2;
  const double coefficients = MonomialCount(height.degree);
  if (effective <= coefficients + 2.0) return -1.0;
  double sum_wr2 = 0.0;
  for (const auto& [index, distance_squared] : neighbors) {
    const double w = tangential_weight(points[index]);
    if (w <= 0.0) continue;
    const Vec3 local = (points[index] - frame.mean) * inv_r;
    const double r = local.dot(frame.normal) -
                     height.Evaluate(local.dot(frame.tangent_u), local.dot(frame.tangent_v));
    sum_wr2 += w * r * r;
  }
  const double variance = sum_wr2 / sum_w * effective / (effective - coefficients);
  return std::sqrt(variance) * radius;
}

}  // namespace

NoiseEstimate EstimateNoise(const std::vector<Vec3>& points, const KdTree& tree, double d,
                            std::span<const std::uint32_t> candidates,
                            const NoiseEstimateOptions& options, const StopCheck& should_stop,
                            int threads) {
  NoiseEstimate estimate;
  const std::size_t pool = candidates.empty() ? points.size() : candidates.size();
  if (pool == 0 || !(d > 0.0)) return estimate;
  std::mt19937_64 rng(options.seed);
  std::uniform_int_distribution<std::size_t> pick(0, pool - 1);
  std::vector<Vec3> probes(static_cast<std::size_t>(options.probes));
  for (Vec3& p : probes) {
    const std::size_t i = pick(rng);
    p = points[candidates.empty() ? i : candidates[i]];
  }
  std::vector<double> probe_sigmas(probes.size()), sigmas;
  sigmas.reserve(probes.size());
  double radius = options.min_fit_radius_d * d;
  for (int round = 0; round < options.max_rounds; ++round) {
    const bool finished = ParallelForUntilStopped<RadiusNeighbors>(
        probes.size(), threads, should_stop,
        [&](std::size_t i, RadiusNeighbors& neighbors) {
          probe_sigmas[i] = ProbeSigma(points, tree, probes[i], radius, neighbors);
        },
        16, 16);
    if (!finished) return NoiseEstimate{.stopped = true};
    sigmas.clear();
    for (double sigma : probe_sigmas) {
      if (sigma >= 0.0) sigmas.push_back(sigma);
    }
    if (sigmas.empty()) return NoiseEstimate{};
    auto middle = sigmas.begin() + static_cast<std::ptrdiff_t>(sigmas.size() / 2);
    std::nth_element(sigmas.begin(), middle, sigmas.end());
    estimate.sigma_d = *middle / d;
    estimate.fit_radius_d = radius / d;
    estimate.probes = static_cast<int>(sigmas.size());
    const double wanted = kRadiusPerSigma * *middle;
    if (wanted <= radius * 1.05) break;  // the neighbourhoods were wide enough for this noise
    radius = wanted;
  }
  return estimate;
}

}  // namespace mlsreg
