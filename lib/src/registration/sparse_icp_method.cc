// The Sparse ICP methods: the correspondence policies (CP, MLS, reverse calibration), the Sparse
// ICP step that filters their partners and runs the ADMM, and the composite methods built from
// it (ST-SICP, CP-SICP+MLS-SICP).
#include <algorithm>
#include <memory>
#include <optional>
#include <utility>

#include "absl/strings/str_cat.h"
#include "icp_loop.h"
#include "method_runners.h"
#include "mlsreg/core/stop_check.h"
#include "mlsreg/correspondences/correspondence_filter.h"
#include "mlsreg/correspondences/correspondence_finders.h"
#include "mlsreg/geometry/kd_tree.h"
#include "mlsreg/geometry/mls_projector.h"
#include "mlsreg/geometry/mls_radius.h"
#include "mlsreg/geometry/sampling.h"
#include "mlsreg/geometry/surface_analysis.h"
#include "mlsreg/solvers/sparse_icp.h"

namespace mlsreg::internal {
namespace {

MlsOptions MlsOptionsFor(const Target& target, const RegistrationOptions& options) {
  MlsOptions mls;
  // Register resolves an automatic radius before any method runs.
  mls.radius = options.mls.radius_d.value_or(kMinAutoMlsRadiusD) * target.sampling_distance();
  mls.polynomial_degree = options.mls.polynomial_degree;
  mls.max_iterations = options.mls.max_iterations;
  return mls;
}

// The filters of the fine phase, and of the coarse phase of a coarse-to-fine finder (see
// CoarsePhaseFilters).
struct PhaseFilters {
  CorrespondenceFilter fine;
  CorrespondenceFilter coarse;
};

PhaseFilters MakeFilters(const FilterParams& params, double d, bool source_oriented,
                         bool target_oriented) {
  CorrespondenceFilterOptions fine;
  fine.min_normal_dot = params.min_normal_dot;
  fine.min_curvature_ratio = params.min_curvature_ratio;
  if (params.max_distance_d > 0.0) fine.max_distance = params.max_distance_d * d;
  fine.source_oriented = source_oriented;
  fine.target_oriented = target_oriented;
  CorrespondenceFilterOptions coarse = fine;
  if (params.coarse_phase != CoarsePhaseFilters::kAll) coarse.min_curvature_ratio = 0.0;
  if (params.coarse_phase == CoarsePhaseFilters::kNone) coarse.min_normal_dot = -1.0;
  return {CorrespondenceFilter(fine), CorrespondenceFilter(coarse)};
}

// One Sparse ICP iteration: the finder's partners for the moved samples, filtered, then the
// ADMM's rigid step. Per-iteration buffers are allocated once.
class SparseIcpStep final : public IcpStep {
 public:
  SparseIcpStep(std::vector<Vec3> samples, SurfaceProperties surface,
                std::unique_ptr<CorrespondenceFinder> finder, const RegistrationOptions& options,
                double d, bool drop_first_rejections, int threads)
      : record_fates_next_(drop_first_rejections),
        samples_(std::move(samples)),
        surface_(std::move(surface)),
        finder_(std::move(finder)),
        filters_(MakeFilters(options.filter, d, surface_.oriented, finder_->oriented_normals())),
        solver_(SolverOptions(options, d, *finder_)),
        damping_(Damping(options, *finder_)),
        base_unit_(options.sicp_length_unit_d * d),
        unit_per_residual_(options.sicp_unit_per_residual),
        stop_length_(options.convergence_d * d),
        d_(d),
        moved_(samples_.size()),
        moved_normals_(samples_.size()),
        partner_points_(samples_.size()),
        partner_normals_(samples_.size()),
        correspondences_(samples_.size()),
        accepted_(samples_.size()) {
    // Sliding is damped once every partner is a foot point: not in a coarse phase, whose far
    // queries are seeded from target samples.
    solver_.set_tangential_weight(finder_->can_refine() ? 0.0 : damping_);
    solver_.set_threads(threads);
    solver_.Reset(samples_.size());
    residuals_.reserve(samples_.size());
  }

  bool Match(const RigidTransform& pose, IterationReport& report) override {
    if (!first_fates_.empty()) DropRejected();
    const std::size_t m = samples_.size();
    for (std::size_t i = 0; i < m; ++i) {
      moved_[i] = pose * samples_[i];
      moved_normals_[i] = pose.linear() * surface_.normals[i];
    }
    finder_->Find(moved_, correspondences_);
    const CorrespondenceFilter& filter = finder_->can_refine() ? filters_.coarse : filters_.fine;
    const bool record_fates = std::exchange(record_fates_next_, false);
    if (record_fates) first_fates_.resize(m);
    report.counts = filter.Apply(
        moved_, moved_normals_, surface_.curvature, surface_.valid, correspondences_, accepted_,
        record_fates ? std::span<PairFate>(first_fates_) : std::span<PairFate>());
    double sum_squared = 0.0;
    for (std::size_t i = 0; i < m; ++i) {
      partner_points_[i] = correspondences_[i].point;
      partner_normals_[i] = correspondences_[i].normal;
      if (accepted_[i]) sum_squared += (moved_[i] - partner_points_[i]).squaredNorm();
    }
    SetRmse(report, sum_squared, d_);
    report.counts += dropped_counts_;
    return true;  // a Find stopped part-way is caught by the loop's own stop check
  }

  std::optional<RigidTransform> Solve(IterationReport& report) override {
    AdaptLengthUnit();
    const RigidTransform increment =
        solver_.Step(moved_, partner_points_, partner_normals_, accepted_);
    report.admm_iterations = solver_.last_outer_iterations();
    return increment;
  }

  std::span<const Vec3> moved_samples() const override { return moved_; }  // moved by Step
  std::span<const Vec3> samples() const override { return samples_; }
  bool coarse() const override { return finder_->can_refine(); }
  // The fine phase projects exactly only the samples that can still be matched: those whose
  // last coarse partners (the MLS patches') pass the fine filters, and of these, those its own
  // first match accepts. From a converged coarse pose a sample outside the overlap, or on
  // surface the filters refuse, stays so (the rejection counts of later fine iterations differ
  // by a few in a thousand), and on the bunny pair more than half of the samples are refused at
  // every fine iteration. The README's departures give the accuracy and time measured.
  void Refine() override {
    first_fates_.resize(samples_.size());
    filters_.fine.Apply(moved_, moved_normals_, surface_.curvature, surface_.valid,
                        correspondences_, accepted_, first_fates_);
    DropRejected();
    finder_->Refine();
    solver_.set_tangential_weight(damping_);
    record_fates_next_ = true;
  }

 private:
  // Keeps only the samples the recorded match accepted (first_fates_: the first match with
  // drop_first_rejections, or the fine phase's first); the others' fates go to dropped_counts_.
  // The finder keeps its per-sample state (warm starts) for the samples kept.
  void DropRejected() {
    kept_indices_.clear();
    std::size_t kept = 0;
    for (std::size_t i = 0; i < samples_.size(); ++i) {
      if (first_fates_[i] != PairFate::kMatched) {
        dropped_counts_.Add(first_fates_[i]);
        continue;
      }
      kept_indices_.push_back(static_cast<std::uint32_t>(i));
      samples_[kept] = samples_[i];
      surface_.normals[kept] = surface_.normals[i];
      surface_.curvature[kept] = surface_.curvature[i];
      surface_.valid[kept] = surface_.valid[i];
      ++kept;
    }
    for (auto* v : {&samples_, &surface_.normals, &moved_, &moved_normals_, &partner_points_,
                    &partner_normals_}) {
      v->resize(kept);
    }
    surface_.curvature.resize(kept);
    surface_.valid.resize(kept);
    correspondences_.resize(kept);
    accepted_.resize(kept);
    solver_.Reset(kept);
    finder_->KeepOnly(kept_indices_);
    first_fates_ = {};
  }

  // Grows the solver's unit to unit_per_residual_ median accepted residuals when that exceeds
  // the base unit (see RegistrationOptions::sicp_unit_per_residual).
  void AdaptLengthUnit() {
    if (unit_per_residual_ <= 0.0) return;
    residuals_.clear();
    for (std::size_t i = 0; i < samples_.size(); ++i) {
      if (accepted_[i]) residuals_.push_back((moved_[i] - partner_points_[i]).norm());
    }
    if (residuals_.empty()) return;
    auto middle = residuals_.begin() + static_cast<std::ptrdiff_t>(residuals_.size() / 2);
    std::nth_element(residuals_.begin(), middle, residuals_.end());
    const double unit = std::max(base_unit_, unit_per_residual_ * *middle);
    solver_.set_length_unit(unit, stop_length_ / unit);
  }

  static SparseIcpOptions SolverOptions(const RegistrationOptions& options, double d,
                                        const CorrespondenceFinder&) {
    SparseIcpOptions sicp = options.sicp;
    sicp.length_unit = options.sicp_length_unit_d * d;
    sicp.stop = options.convergence_d / options.sicp_length_unit_d;
    return sicp;
  }
  static double Damping(const RegistrationOptions& options, const CorrespondenceFinder& finder) {
    return options.sicp.metric == SicpMetric::kPointToPlane && finder.foot_points()
               ? options.tangential_damping
               : 0.0;
  }

  bool record_fates_next_;             // the next match records first_fates_
  std::vector<PairFate> first_fates_;  // recorded; the match after drops the rejected samples
  std::vector<std::uint32_t> kept_indices_;
  CorrespondenceCounts dropped_counts_;  // the fates of the samples dropped
  std::vector<Vec3> samples_;
  SurfaceProperties surface_;
  std::unique_ptr<CorrespondenceFinder> finder_;
  PhaseFilters filters_;
  SparseIcpSolver solver_;
  double damping_;
  double base_unit_, unit_per_residual_, stop_length_;
  double d_;
  std::vector<Vec3> moved_, moved_normals_, partner_points_, partner_normals_;
  std::vector<Correspondence> correspondences_;
  std::vector<std::uint8_t> accepted_;
  std::vector<double> residuals_;  // scratch of AdaptLengthUnit, capacity = samples
};

// ST-SICP's target: every target sample projected onto the target's own MLS surface (de-noised;
// samples whose projection fails keep their position), prepared like any target but keeping the
// original surface variation for the curvature filter (see Target::WithMovedPoints). Asks
// `should_stop` (may be empty) every few dozen points, since a large target takes seconds; null
// when it said stop.
absl::StatusOr<std::shared_ptr<const Target>> SmoothedTarget(const Target& target,
                                                             const RegistrationOptions& options,
                                                             const StopCheck& should_stop,
                                                             int threads) {
  const MlsProjector projector(target.points(), target.tree(), MlsOptionsFor(target, options));
  const std::vector<Vec3>& points = target.points();
  std::vector<Vec3> smoothed(points.size());
  const bool finished = ProjectEach(
      projector, points.size(), [&](std::size_t i) -> const Vec3& { return points[i]; },
      [&](std::size_t i, const MlsProjection& projection, const MlsProjector::Workspace&) {
        smoothed[i] = projection.status == ProjectionStatus::kOk ? projection.point : points[i];
      },
      threads, should_stop);
  if (!finished) return std::shared_ptr<const Target>();
  return target.WithMovedPoints(std::move(smoothed));
}

// Adds a later phase's result to an earlier one's: one trace, summed phase timings.
}  // namespace

void AppendPhase(RegistrationResult& total, RegistrationResult&& phase) {
  total.transform = phase.transform;
  total.num_samples = phase.num_samples;  // the samples of the phase that decided the result
  total.converged = phase.converged;
  total.termination = phase.termination;
  total.iterations += phase.iterations;
  for (IterationReport& r : phase.trace) total.trace.push_back(std::move(r));
  total.timings.preprocessing += phase.timings.preprocessing;
  total.timings.subsampling += phase.timings.subsampling;
  total.timings.matching += phase.timings.matching;
  total.timings.optimisation += phase.timings.optimisation;
}

SourceSamples SubsampleSource(const PointCloud& source, const RegistrationOptions& options,
                              RegistrationResult& result) {
  const Clock::time_point phase = Clock::now();
  SourceSamples samples;
  samples.indices =
      RandomSubsample(source.size(), static_cast<std::size_t>(options.num_samples), options.seed);
  samples.points.reserve(samples.indices.size());
  for (std::uint32_t i : samples.indices) samples.points.push_back(source.points[i]);
  result.num_samples = static_cast<int>(samples.indices.size());
  result.timings.subsampling = Seconds(phase);
  return samples;
}

std::unique_ptr<CorrespondenceFinder> MakeClosestPointFinder(const Target& target,
                                                             const RegistrationOptions&) {
  return std::make_unique<ClosestPointFinder>(target);
}

std::unique_ptr<CorrespondenceFinder> MakeMlsFinder(const Target& target,
                                                    const RegistrationOptions& options) {
  return std::make_unique<MlsCorrespondenceFinder>(target, MlsOptionsFor(target, options),
                                                   options.mls.warm_start, options.mls.far_queries,
                                                   options.mls.projection);
}

std::unique_ptr<CorrespondenceFinder> MakeBilinearFinder(const Target& target,
                                                         const RegistrationOptions&) {
  return std::make_unique<ReverseCalibrationFinder>(
      target, ReverseCalibrationFinder::Interpolation::kBilinear);
}

std::unique_ptr<CorrespondenceFinder> MakePhongFinder(const Target& target,
                                                      const RegistrationOptions&) {
  return std::make_unique<ReverseCalibrationFinder>(
      target, ReverseCalibrationFinder::Interpolation::kPhong);
}

absl::StatusOr<RegistrationResult> RunSparseIcp(const RegistrationProblem& problem) {
  const Target& target = *problem.target;
  const RegistrationOptions& options = *problem.options;
  RegistrationResult result;
  const double d = target.sampling_distance();
  result.sampling_distance = d;
  SourceSamples sampled = SubsampleSource(*problem.source, options, result);

  // Preprocessing: source normals and surface variation at the samples, at the scale of the
  // partners.
  const Clock::time_point phase = Clock::now();
  std::unique_ptr<CorrespondenceFinder> finder =
      SpecOf(options.method).make_finder(target, options);
  finder->set_should_stop(problem.callbacks->should_stop);
  finder->set_threads(problem.threads);
  const double analysis_radius = finder->analysis_radius() > 0.0
                                     ? finder->analysis_radius()
                                     : target.options().analysis_radius_d * d;
  std::optional<KdTree> own_tree;
  if (!problem.source_tree) own_tree.emplace(problem.source->points, problem.threads);
  const KdTree& source_tree = problem.source_tree ? *problem.source_tree : *own_tree;
  SurfaceProperties surface =
      problem.source_surface
          ? problem.source_surface->At(analysis_radius, sampled.indices,
                                       problem.callbacks->should_stop, problem.threads)
          : AnalyzeSurface(problem.source->points, source_tree, analysis_radius,
                           problem.source->viewpoint, sampled.indices,
                           problem.callbacks->should_stop, problem.threads);
  result.timings.preprocessing = Seconds(phase);
  const RigidTransform start_pose(Orthonormalize(problem.initial));
  if (surface.stopped) {
    result.termination = Termination::kCancelled;
    result.transform = start_pose.matrix();
    result.timings.total = Seconds(problem.start);
    return result;
  }

  SparseIcpStep step(std::move(sampled.points), std::move(surface), std::move(finder), options, d,
                     problem.drop_first_rejections, problem.threads);
  LoopSettings settings;
  settings.rule = StopRule::kRecentPoses;
  settings.max_iterations = options.max_iterations;
  settings.min_correspondences = options.min_correspondences;
  settings.convergence = options.convergence_d * d;
  settings.coarse_convergence = options.coarse_convergence_d * d;
  settings.stall = options.stall_d * d;
  settings.noise_stall = options.stall_noise_fraction * problem.noise_d * d;
  settings.stall_standard_errors = options.stall_standard_errors;
  settings.iteration_offset = problem.iteration_offset;
  RunIcpLoop(step, start_pose, settings, *problem.callbacks, problem.start, result);
  result.timings.total = Seconds(problem.start);
  return result;
}

absl::StatusOr<RegistrationResult> RunSmoothedTargetSicp(const RegistrationProblem& problem) {
  const Clock::time_point phase = Clock::now();
  auto smoothed = SmoothedTarget(*problem.target, *problem.options, problem.callbacks->should_stop,
                                 problem.threads);
  if (!smoothed.ok()) return smoothed.status();
  if (*smoothed == nullptr) {  // cancelled while smoothing: no iteration ran
    RegistrationResult result =
        CancelledBeforeIterations(problem.initial, problem.target->sampling_distance());
    result.timings.preprocessing = Seconds(phase);
    return result;
  }
  const double smoothing = Seconds(phase);
  RegistrationProblem on_smoothed = problem;
  on_smoothed.target = smoothed->get();
  auto result = RunSparseIcp(on_smoothed);
  if (!result.ok()) return result;
  result->timings.preprocessing += smoothing;
  result->sampling_distance = problem.target->sampling_distance();
  return result;
}

absl::StatusOr<RegistrationResult> RunCpThenMlsSicp(const RegistrationProblem& problem) {
  // Phase 1: CP-SICP to convergence without filtering (paper section 5.2.2).
  RegistrationOptions coarse = *problem.options;
  coarse.method = Method::kCpSicp;
  coarse.filter.min_normal_dot = -1.0;
  coarse.filter.min_curvature_ratio = 0.0;
  RegistrationProblem first = problem;
  first.options = &coarse;
  auto result = RunSparseIcp(first);
  if (!result.ok() || result->termination == Termination::kCancelled) return result;
  // Phase 2: MLS-SICP from there.
  RegistrationOptions fine = *problem.options;
  fine.method = Method::kMlsSicp;
  RegistrationProblem second = problem;
  second.options = &fine;
  second.initial = result->transform;
  second.iteration_offset = result->iterations;
  auto phase = RunSparseIcp(second);
  if (!phase.ok()) return phase.status();
  AppendPhase(*result, *std::move(phase));
  return result;
}

}  // namespace mlsreg::internal
