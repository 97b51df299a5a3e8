#include "mlsreg/evaluation/evaluation.h"

#include <atomic>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <numbers>
#include <random>
#include <thread>

#include "absl/strings/str_cat.h"
#include "mlsreg/core/transform.h"
#include "mlsreg/io/io.h"

namespace mlsreg {
namespace {

// Clouds and targets are loaded once each, on first use, and shared by all runs.
class CloudCache {
 public:
  absl::StatusOr<std::shared_ptr<const PointCloud>> Source(const std::string& path) {
    Entry& e = Get(path);
    std::call_once(e.cloud_once, [&] {
      auto cloud = ReadPointCloud(path);
      if (cloud.ok()) {
        e.cloud = std::make_shared<const PointCloud>(*std::move(cloud));
      } else {
        e.cloud_status = cloud.status();
      }
    });
    if (!e.cloud_status.ok()) return e.cloud_status;
    return e.cloud;
  }

  absl::StatusOr<std::shared_ptr<const Target>> TargetFor(const std::string& path) {
    auto cloud = Source(path);
    if (!cloud.ok()) return cloud.status();
    Entry& e = Get(path);
    std::call_once(e.target_once, [&] {
      auto target = Target::Build(**cloud);
      if (target.ok()) {
        e.target = *target;
      } else {
        e.target_status = target.status();
      }
    });
    if (!e.target_status.ok()) return e.target_status;
    return e.target;
  }

 private:
  struct Entry {
    std::once_flag cloud_once, target_once;
    std::shared_ptr<const PointCloud> cloud;
    absl::Status cloud_status;
    std::shared_ptr<const Target> target;
    absl::Status target_status;
  };
  Entry& Get(const std::string& path) {
    std::lock_guard<std::mutex> lock(mutex_);
    std::unique_ptr<Entry>& e = entries_[path];
    if (!e) e = std::make_unique<Entry>();
    return *e;
  }
  std::mutex mutex_;
  std::map<std::string, std::unique_ptr<Entry>> entries_;
};

Vec3 TransformedCentroid(const PointCloud& cloud, const Matrix4& m) {
  const Vec3 c = Centroid(cloud.points);
  return m.topLeftCorner<3, 3>() * c + m.topRightCorner<3, 1>();
}

ProblemOutcome RunOne(const ManifestProblem& problem, std::size_t index, Method method,
                      const EvaluationOptions& options, CloudCache& cache) {
  ProblemOutcome out;
  out.problem_index = index;
  out.method = method;
  auto source = cache.Source(problem.source_path);
  if (!source.ok()) {
    out.status = source.status();
    return out;
  }
  auto target = cache.TargetFor(problem.target_path);
  if (!target.ok()) {
    out.status =
        absl::Status(target.status().code(), absl::StrCat("target: ", target.status().message()));
    return out;
  }
  const double d = (*target)->sampling_distance();
  out.target_build_seconds = (*target)->build_seconds();
  const Matrix4& truth = *problem.ground_truth;
  const Matrix4 base = problem.initial.value_or(truth);
  out.initial = PerturbedStart(**source, base, d, options.perturbation, index);
  out.initial_error = EvaluatePose((*source)->points, out.initial, truth, d);
  RegistrationOptions registration = options.registration;
  registration.method = method;
  auto result = Register(**target, **source, out.initial, registration, {},
                         ExecutionOptions{options.threads});
  if (!result.ok()) {
    out.status = result.status();
    return out;
  }
  out.result = *std::move(result);
  out.error = EvaluatePose((*source)->points, out.result.transform, truth, d);
  out.trace_error_d.reserve(out.result.trace.size());
  for (const IterationReport& it : out.result.trace) {
    out.trace_error_d.push_back(EvaluatePose((*source)->points, it.transform, truth, d).rmse_d);
  }
  return out;
}

}  // namespace

// The rotation angle of a rotation uniform on SO(3), from u uniform in [0, 1): its density is
// (1 - cos a) / pi on [0, pi], so its distribution function (a - sin a) / pi is inverted by
// bisection.
static double UniformRotationAngleDeg(double u) {
  double lo = 0.0, hi = std::numbers::pi;
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    ((mid - std::sin(mid)) / std::numbers::pi < u ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi) * 180.0 / std::numbers::pi;
}

Matrix4 PerturbedStart(const PointCloud& source, const Matrix4& initial, double d,
                       const PerturbationProtocol& protocol, std::size_t index) {
  if (protocol.angle_deg == 0.0 && protocol.translation_d == 0.0 && !protocol.uniform_rotation) {
    return initial;
  }
  const std::uint64_t seed = protocol.seed * 1000003ULL + index;
  double angle_deg = protocol.angle_deg;
  double translation_d = protocol.translation_d;
  if (protocol.uniform_rotation || protocol.translation_max_d > protocol.translation_d) {
    std::mt19937_64 rng(seed ^ 0x9E3779B97F4A7C15ULL);  // independent of the axis draws
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    const double u = unit(rng), v = unit(rng);
    if (protocol.uniform_rotation) angle_deg = UniformRotationAngleDeg(u);
    if (protocol.translation_max_d > protocol.translation_d) {
      translation_d += v * (protocol.translation_max_d - protocol.translation_d);
    }
  }
  return RandomPerturbation(angle_deg, translation_d * d, TransformedCentroid(source, initial),
                            seed) *
         initial;
}

absl::StatusOr<std::vector<ProblemOutcome>> RunEvaluation(
    const Manifest& manifest, const EvaluationOptions& options,
    const std::function<void(const ProblemOutcome&, std::size_t, std::size_t)>& on_done) {
  std::vector<std::size_t> problems = options.problems;
  if (problems.empty()) {
    for (std::size_t i = 0; i < manifest.problems.size(); ++i) problems.push_back(i);
  }
  for (std::size_t index : problems) {
    if (index >= manifest.problems.size()) {
      return absl::InvalidArgumentError(absl::StrCat("problem index ", index, " is out of range (",
                                                     manifest.problems.size(), " problems)"));
    }
    if (!manifest.problems[index].ground_truth) {
      return absl::InvalidArgumentError(absl::StrCat("problem '", manifest.problems[index].id,
                                                     "' has no ground truth (column gt)"));
    }
  }
  const std::size_t methods = options.methods.size();
  const std::size_t total = problems.size() * methods;
  std::vector<ProblemOutcome> outcomes(total);
  CloudCache cache;
  std::atomic<std::size_t> next{0};
  std::mutex report_mutex;
  std::size_t done = 0;
  auto worker = [&] {
    for (std::size_t task = next++; task < total; task = next++) {
      const std::size_t index = problems[task / methods];
      outcomes[task] =
          RunOne(manifest.problems[index], index, options.methods[task % methods], options, cache);
      std::lock_guard<std::mutex> lock(report_mutex);
      ++done;
      if (on_done) on_done(outcomes[task], done, total);
    }
  };
  const int jobs = std::max(1, std::min<int>(options.jobs, static_cast<int>(total)));
  std::vector<std::thread> threads;
  for (int j = 1; j < jobs; ++j) threads.emplace_back(worker);
  worker();
  for (std::thread& t : threads) t.join();
  return outcomes;
}

}  // namespace mlsreg
