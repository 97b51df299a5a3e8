// Speed of the registration core on a real scan pair (bundled Stanford bunny bun000 -> bun045).
// Run: build/bench/mlsreg_bench  (report ratios between rows of one run; the machine is noisy).
#include <benchmark/benchmark.h>

#include <array>
#include <memory>
#include <numbers>

#include "mlsreg/geometry/feature_cloud.h"
#include "mlsreg/geometry/mls_patches.h"
#include "mlsreg/geometry/mls_projector.h"
#include "mlsreg/geometry/sampling.h"
#include "mlsreg/io/io.h"
#include "mlsreg/io/manifest.h"
#include "mlsreg/multiview/align_scans.h"
#include "mlsreg/multiview/merged_cloud.h"
#include "mlsreg/registration/global_candidates.h"
#include "mlsreg/registration/registration.h"
#include "mlsreg/registration/verification.h"
#include "support/synthetic.h"

namespace mlsreg {
namespace {

struct BunnyPair {
  PointCloud source;
  std::shared_ptr<const Target> target;
  Matrix4 truth;
  std::vector<Vec3> queries;  // 2,000 source samples placed by the ground truth
};

const BunnyPair& Pair() {
  static const BunnyPair pair = [] {
    BunnyPair p;
    const std::string dir = std::string(MLSREG_SOURCE_DIR) + "/data/bunny/";
    auto manifest = ReadManifest(dir + "pairs.csv");
    const ManifestProblem& problem = manifest->problems.at(0);
    p.source = *ReadPointCloud(problem.source_path);
    p.target = *Target::Build(*ReadPointCloud(problem.target_path));
    p.truth = *problem.ground_truth;
    for (std::uint32_t i : RandomSubsample(p.source.size(), 2000, 1)) {
      p.queries.push_back(p.truth.topLeftCorner<3, 3>() * p.source.points[i] +
                          p.truth.topRightCorner<3, 1>());
    }
    return p;
  }();
  return pair;
}

void BM_ClosestPoint(benchmark::State& state) {
  const BunnyPair& p = Pair();
  for (auto _ : state) {
    for (const Vec3& q : p.queries) benchmark::DoNotOptimize(p.target->tree().Nearest(q));
  }
  state.SetItemsProcessed(state.iterations() * p.queries.size());
}
BENCHMARK(BM_ClosestPoint)->Unit(benchmark::kMicrosecond);

// Argument: support radius r in units of d. Cold projections (Algorithm 1 from the query).
void BM_MlsProjection(benchmark::State& state) {
  const BunnyPair& p = Pair();
  MlsOptions options;
  options.radius = static_cast<double>(state.range(0)) * p.target->sampling_distance();
  const MlsProjector projector(p.target->points(), p.target->tree(), options);
  MlsProjector::Workspace workspace;
  for (auto _ : state) {
    for (const Vec3& q : p.queries) benchmark::DoNotOptimize(projector.Project(q, workspace));
  }
  state.SetItemsProcessed(state.iterations() * p.queries.size());
}
BENCHMARK(BM_MlsProjection)->Arg(5)->Arg(8)->Unit(benchmark::kMillisecond);

// Argument: r in units of d. The same queries through MLS patches (geometry/mls_patches.h) built
// at r: cold (two blends, as at a registration's first iteration) and warm (one blend from the
// query on its previous projection's tangent plane, as in every later iteration).
MlsPatches PatchesAt(const BunnyPair& p, double radius_d) {
  MlsOptions options;
  options.radius = radius_d * p.target->sampling_distance();
  return *MlsPatches::Build(p.target->points(), p.target->tree(), options, std::nullopt,
                            PatchFitting::kAll, 1);
}

void BM_MlsPatchProjection(benchmark::State& state) {
  const BunnyPair& p = Pair();
  const MlsPatches patches = PatchesAt(p, static_cast<double>(state.range(0)));
  for (auto _ : state) {
    for (const Vec3& q : p.queries) benchmark::DoNotOptimize(patches.Project(q, true));
  }
  state.SetItemsProcessed(state.iterations() * p.queries.size());
}
BENCHMARK(BM_MlsPatchProjection)->Arg(5)->Arg(8)->Unit(benchmark::kMicrosecond);

// Second argument 1: each query keeps its AnchorCache from the previous projection, as the
// MLS correspondence finder does (0: the anchors from the k-d tree every time).
void BM_MlsPatchProjectionWarm(benchmark::State& state) {
  const BunnyPair& p = Pair();
  const MlsPatches patches = PatchesAt(p, static_cast<double>(state.range(0)));
  const bool cached = state.range(1) != 0;
  // Previous projections of queries displaced by 0.5 d, as one ICP iteration moves them.
  const double d = p.target->sampling_distance();
  std::vector<Vec3> starts;
  std::vector<MlsPatches::AnchorCache> caches(p.queries.size());
  for (std::size_t i = 0; i < p.queries.size(); ++i) {
    const Vec3& q = p.queries[i];
    const MlsProjection previous = patches.Project(q + Vec3(0.3, 0.3, 0.3) * d, true, &caches[i]);
    starts.push_back(q - (q - previous.point).dot(previous.normal) * previous.normal);
  }
  for (auto _ : state) {
    for (std::size_t i = 0; i < p.queries.size(); ++i) {
      benchmark::DoNotOptimize(
          patches.ProjectNear(p.queries[i], starts[i], true, cached ? &caches[i] : nullptr));
    }
  }
  state.SetItemsProcessed(state.iterations() * p.queries.size());
}
BENCHMARK(BM_MlsPatchProjectionWarm)
    ->Args({5, 0})
    ->Args({5, 1})
    ->Args({8, 0})
    ->Args({8, 1})
    ->Unit(benchmark::kMicrosecond);

// An ICP fine phase's exact projections: the 2,000 queries walk 20 steps of 0.005 r each in a
// fixed direction (about how far a sample moves per fine iteration, docs/evaluation.md), each
// projection warm-started on its previous projection's tangent plane as the MLS correspondence
// finder does. Argument 1: every query keeps its neighbourhood (KeptNeighborhood); 0: the tree is
// searched at every projection. r = 5 d.
void BM_MlsFineWalk(benchmark::State& state) {
  const BunnyPair& p = Pair();
  MlsOptions options;
  options.radius = 5.0 * p.target->sampling_distance();
  const MlsProjector projector(p.target->points(), p.target->tree(), options);
  const bool keep = state.range(0) != 0;
  constexpr int kSteps = 20;
  const Vec3 step = Vec3(1.0, 0.5, -0.3).normalized() * (0.005 * options.radius);
  MlsProjector::Workspace workspace;
  std::vector<KeptNeighborhood> kept(p.queries.size());
  std::vector<MlsProjection> previous(p.queries.size());
  for (auto _ : state) {
    for (KeptNeighborhood& k : kept) k.reach = -1.0;
    for (std::size_t i = 0; i < p.queries.size(); ++i) {
      previous[i] = projector.Project(p.queries[i], workspace);
    }
    for (int s = 1; s <= kSteps; ++s) {
      for (std::size_t i = 0; i < p.queries.size(); ++i) {
        const Vec3 q = p.queries[i] + s * step;
        const MlsProjection& last = previous[i];
        const Vec3 start = q - (q - last.point).dot(last.normal) * last.normal;
        previous[i] = projector.ProjectFrom(start, workspace, keep ? &kept[i] : nullptr);
      }
    }
    benchmark::DoNotOptimize(previous.data());
  }
  state.SetItemsProcessed(state.iterations() * p.queries.size() * kSteps);
}
BENCHMARK(BM_MlsFineWalk)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Argument 0: every part on first use (the library's default: a one-shot registration), 1: every
// part with the target (surface, patch fits, features), 2: as a served target (surface and
// features with the target, patch fits on first use). Counter bytes_per_point:
// Target::MemoryBytes() / points right after the build.
void BM_TargetBuild(benchmark::State& state) {
  const BunnyPair& p = Pair();
  TargetOptions options;
  if (state.range(0) >= 1) options = TargetOptions::AllWithTarget();
  if (state.range(0) == 2) options.mls_patch_fits = PartBuild::kOnFirstUse;
  std::size_t bytes = 0;
  for (auto _ : state) {
    auto target = Target::Build(p.target->cloud(), options);
    bytes = (*target)->MemoryBytes();
    benchmark::DoNotOptimize(target);
  }
  state.SetItemsProcessed(state.iterations() * p.target->cloud().size());
  state.counters["bytes_per_point"] =
      static_cast<double>(bytes) / static_cast<double>(p.target->cloud().size());
}
BENCHMARK(BM_TargetBuild)->DenseRange(0, 2)->Unit(benchmark::kMillisecond);

// MLS-SICP with each MLS projection (argument: 0 patches then exact, the default; 1 patches
// only; 2 exact only).
void BM_MlsSicpProjection(benchmark::State& state) {
  const BunnyPair& p = Pair();
  RegistrationOptions options;
  options.method = Method::kMlsSicp;
  options.mls.projection = static_cast<MlsProjectionKind>(state.range(0));
  const Matrix4 initial =
      RandomPerturbation(10.0, 10.0 * p.target->sampling_distance(), Vec3::Zero(), 1) * p.truth;
  int iterations = 0;
  for (auto _ : state) {
    auto result = Register(*p.target, p.source, initial, options);
    iterations = result->iterations;
    benchmark::DoNotOptimize(result);
  }
  state.counters["iterations"] = iterations;
}
BENCHMARK(BM_MlsSicpProjection)->DenseRange(0, 2)->Unit(benchmark::kMillisecond);

// Argument: index into AllMethods() (auto, cp-sicp, mls-sicp, st-sicp, cp-sicp+mls-sicp, g-icp,
// fgr).
// One full registration from the evaluation protocol's start pose (10 degrees, 10 d from the
// ground truth), 2,000 samples, paper parameters.
void BM_Registration(benchmark::State& state) {
  const BunnyPair& p = Pair();
  RegistrationOptions options;
  options.method = AllMethods().at(static_cast<std::size_t>(state.range(0)));
  const Matrix4 initial =
      RandomPerturbation(10.0, 10.0 * p.target->sampling_distance(), Vec3::Zero(), 1) * p.truth;
  int iterations = 0;
  for (auto _ : state) {
    auto result = Register(*p.target, p.source, initial, options);
    iterations = result->iterations;
    benchmark::DoNotOptimize(result);
  }
  state.counters["iterations"] = iterations;
  state.SetLabel(std::string(MethodName(options.method)));
}
BENCHMARK(BM_Registration)->DenseRange(0, 6)->Unit(benchmark::kMillisecond);

// The global stage of method auto on one core: the source's voxel samples with normals and FPFH
// features, feature matching against the target's cached features, RANSAC. Argument 0: the bunny
// pair (40k points each); 1: 50k-point clouds (two samplings of a bumpy sheet, the source
// turned by 120 degrees). Counter samples: source feature samples.
struct GlobalProblem {
  PointCloud source;
  std::shared_ptr<const Target> target;
};

const GlobalProblem& GlobalStageProblem(int which) {
  static const std::array<GlobalProblem, 2> problems = [] {
    std::array<GlobalProblem, 2> out;
    out[0] = {Pair().source, Pair().target};
    const Matrix4 turn = RandomPerturbation(120.0, 0.3, Vec3::Zero(), 7);
    PointCloud sheet = testing::SampleBumpySurface(50'000, -1.0, 1.0, 1, 0.002);
    PointCloud source = testing::SampleBumpySurface(50'000, -1.0, 1.0, 2, 0.002);
    for (Vec3& x : source.points) x = turn.topLeftCorner<3, 3>() * x + turn.topRightCorner<3, 1>();
    out[1] = {std::move(source), *Target::Build(std::move(sheet))};
    return out;
  }();
  return problems.at(static_cast<std::size_t>(which));
}

void BM_GlobalStage(benchmark::State& state) {
  const GlobalProblem& p = GlobalStageProblem(static_cast<int>(state.range(0)));
  const Target& target = *p.target;
  const double d = target.sampling_distance();
  const KdTree source_tree(p.source.points);  // built by every registration anyway
  std::size_t samples = 0, candidates = 0;
  for (auto _ : state) {
    auto features = BuildFeatureCloud(p.source.points, source_tree, nullptr, 5.0 * d,
                                      p.source.viewpoint, target.features()->scale);
    GlobalCandidateOptions options;
    options.inlier_distance = 1.5 * target.features()->scale.voxel;
    const GlobalCandidates found = FindGlobalCandidates(*features, *target.features(), options);
    samples = features->size();
    candidates = found.candidates.size();
    benchmark::DoNotOptimize(found);
  }
  state.counters["samples"] = static_cast<double>(samples);
  state.counters["candidates"] = static_cast<double>(candidates);
}
BENCHMARK(BM_GlobalStage)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Method auto against MLS-SICP near the truth (argument 0: the protocol's 10 degrees / 10 d, where
// auto should stop after its first stage) and from a half turn (1: the whole pipeline).
void BM_AutoMethod(benchmark::State& state) {
  const BunnyPair& p = Pair();
  const bool far = state.range(0) == 1;
  const Matrix4 initial =
      RandomPerturbation(far ? 180.0 : 10.0, (far ? 30.0 : 10.0) * p.target->sampling_distance(),
                         Vec3::Zero(), 1) *
      p.truth;
  const RegistrationOptions options;  // auto, the default
  int candidates = 0;
  for (auto _ : state) {
    auto result = Register(*p.target, p.source, initial, options);
    candidates = static_cast<int>(result->auto_report->candidates.size());
    benchmark::DoNotOptimize(result);
  }
  state.counters["candidates"] = candidates;
}
BENCHMARK(BM_AutoMethod)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Method auto near the truth with its finish (argument 1, the default) and without it (0): what
// polishing the verified pose over every source point, and verifying it again, costs.
void BM_AutoFinish(benchmark::State& state) {
  const BunnyPair& p = Pair();
  const Matrix4 initial =
      RandomPerturbation(10.0, 10.0 * p.target->sampling_distance(), Vec3::Zero(), 1) * p.truth;
  RegistrationOptions options;  // auto, the default
  options.automatic.finish = state.range(0) == 1;
  for (auto _ : state) benchmark::DoNotOptimize(Register(*p.target, p.source, initial, options));
}
BENCHMARK(BM_AutoFinish)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// The verification of the ground-truth pose alone (the source's noise estimate included), one
// thread: what every result's verdict costs.
void BM_VerifyPose(benchmark::State& state) {
  const BunnyPair& p = Pair();
  VerificationScore score;
  for (auto _ : state) {
    score = VerifyPose(*p.target, p.source, p.truth);
    benchmark::DoNotOptimize(score);
  }
  state.counters["samples"] = score.samples;
}
BENCHMARK(BM_VerifyPose)->Unit(benchmark::kMillisecond);

// One registration of `method` from the protocol's start with state.range(0) threads.
void RegisterOnThreads(benchmark::State& state, Method method) {
  const BunnyPair& p = Pair();
  RegistrationOptions options;  // defaults
  options.method = method;
  const Matrix4 initial =
      RandomPerturbation(10.0, 10.0 * p.target->sampling_distance(), Vec3::Zero(), 1) * p.truth;
  const ExecutionOptions execution{static_cast<int>(state.range(0))};
  for (auto _ : state) {
    benchmark::DoNotOptimize(Register(*p.target, p.source, initial, options, {}, execution));
  }
}

// MLS-SICP on the same problem with 1 or 2 threads (argument): the speed-up of one registration.
void BM_MlsSicpThreads(benchmark::State& state) { RegisterOnThreads(state, Method::kMlsSicp); }
BENCHMARK(BM_MlsSicpThreads)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// Method auto (the default) the same way: coarse stage, MLS refinement, the plane-to-plane finish
// over every source point, two verifications.
void BM_AutoThreads(benchmark::State& state) { RegisterOnThreads(state, Method::kAuto); }
BENCHMARK(BM_AutoThreads)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// The target build with 1 or 2 threads (argument).
void BM_TargetBuildThreads(benchmark::State& state) {
  const BunnyPair& p = Pair();
  TargetOptions options = TargetOptions::AllWithTarget();
  options.threads = static_cast<int>(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(Target::Build(p.target->cloud(), options));
  state.SetItemsProcessed(state.iterations() * p.target->cloud().size());
}
BENCHMARK(BM_TargetBuildThreads)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// The k-d tree over the target's points with 1 or 2 threads (argument): nanoflann's tree, its
// subtrees built at once (the same tree for any count).
void BM_KdTreeBuildThreads(benchmark::State& state) {
  const std::vector<Vec3>& points = Pair().target->cloud().points;
  const int threads = static_cast<int>(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(KdTree(points, threads));
  state.SetItemsProcessed(state.iterations() * points.size());
}
BENCHMARK(BM_KdTreeBuildThreads)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// Scene scale: the first KITTI 00 pair of ../shared/data/real (two 124k-point Velodyne scans,
// 3.6 m apart), one thread, defaults, as `mlsreg register` runs it after reading the files.
// Argument 0: the target's build alone; 1: the build and method auto from an odometry-like prior
// (the truth moved by 5 degrees and 1 m, as bench/lidar_peers.py's prior). Skipped when the data
// is not there.
struct LidarPair {
  PointCloud source, target;
  Matrix4 truth = Matrix4::Identity(), prior = Matrix4::Identity();
  bool found = false;
};

const LidarPair& Kitti() {
  static const LidarPair pair = [] {
    LidarPair p;
    const std::string dir =
        std::string(MLSREG_SOURCE_DIR) + "/../shared/data/real/kitti00_f0000-0015/";
    auto manifest = ReadManifest(dir + "pairs.csv");
    if (!manifest.ok() || manifest->problems.empty()) return p;
    const ManifestProblem& problem = manifest->problems.front();
    auto source = ReadPointCloud(problem.source_path);
    auto target = ReadPointCloud(problem.target_path);
    if (!source.ok() || !target.ok() || !problem.ground_truth) return p;
    p.source = *std::move(source);
    p.target = *std::move(target);
    p.truth = *problem.ground_truth;
    Matrix4 moved = Matrix4::Identity();
    moved.topLeftCorner<3, 3>() =
        Eigen::AngleAxisd(5.0 * std::numbers::pi / 180.0, Vec3(1, 2, 3).normalized())
            .toRotationMatrix();
    moved.topRightCorner<3, 1>() = Vec3(0.6, 0.8, 0.0);  // 1 m
    p.prior = moved * p.truth;
    p.found = true;
    return p;
  }();
  return pair;
}

void BM_LidarOneShot(benchmark::State& state) {
  const LidarPair& p = Kitti();
  if (!p.found) {
    state.SkipWithError("../shared/data/real/kitti00_f0000-0015 not found");
    return;
  }
  const bool register_too = state.range(0) == 1;
  RegistrationOptions options;  // defaults: method auto
  double translation_error = 0.0;
  bool verified = false;
  for (auto _ : state) {
    auto target = Target::Build(p.target);
    if (!target.ok()) {
      state.SkipWithError(std::string(target.status().message()).c_str());
      return;
    }
    if (!register_too) {
      benchmark::DoNotOptimize(target);
      continue;
    }
    auto result = Register(**target, p.source, p.prior, options);
    if (!result.ok()) {
      state.SkipWithError(std::string(result.status().message()).c_str());
      return;
    }
    translation_error =
        (result->transform.topRightCorner<3, 1>() - p.truth.topRightCorner<3, 1>()).norm();
    verified = result->verification && result->verification->verified();
    benchmark::DoNotOptimize(result);
  }
  if (register_too) {
    state.counters["translation_error_m"] = translation_error;
    state.counters["verified"] = verified ? 1.0 : 0.0;
  }
}
BENCHMARK(BM_LidarOneShot)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// One verification with 1 or 2 threads (second argument), as Register runs it (the source
// measured, then its working voxels scored; the target's patches fitted by the first run and
// kept, as on a served target). First argument 0: the bunny pair at its true pose; 1: the KITTI
// pair at the pose method auto reaches from the prior (its recorded truth is good to a few cm,
// which the verdict resolves), skipped when the data is not there.
struct VerifyProblem {
  std::shared_ptr<const Target> target;
  const PointCloud* source = nullptr;
  Matrix4 pose = Matrix4::Identity();
};

const VerifyProblem& KittiVerifyProblem() {
  static const VerifyProblem problem = [] {
    VerifyProblem p;
    if (!Kitti().found) return p;
    p.target = *Target::Build(Kitti().target);
    p.source = &Kitti().source;
    p.pose = Register(*p.target, Kitti().source, Kitti().prior, RegistrationOptions{})->transform;
    return p;
  }();
  return problem;
}

void BM_VerifyThreads(benchmark::State& state) {
  const bool lidar = state.range(0) == 1;
  if (lidar && !Kitti().found) {
    state.SkipWithError("../shared/data/real/kitti00_f0000-0015 not found");
    return;
  }
  const VerifyProblem p =
      lidar ? KittiVerifyProblem() : VerifyProblem{Pair().target, &Pair().source, Pair().truth};
  const int threads = static_cast<int>(state.range(1));
  VerificationScore score;
  for (auto _ : state) {
    score = VerifyPose(*p.target, *p.source, p.pose, threads);
    benchmark::DoNotOptimize(score);
  }
  state.counters["samples"] = score.samples;
  state.SetLabel(std::string(VerdictName(score.verdict)));
}
BENCHMARK(BM_VerifyThreads)
    ->ArgsProduct({{0, 1}, {1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// Adversarial inputs: a cluster of 40,000 identical points (plus two outliers), which made every
// neighbourhood the whole cloud. Argument 0: the whole target build; 1: the same build told to
// stop once it started, timing how long the worker stays busy after the request (the
// cancellation latency a server job sees).
PointCloud IdenticalCluster() {
  PointCloud cloud;
  cloud.points.assign(40'000, Vec3(0.1, 0.2, 0.3));
  cloud.points.push_back(Vec3(1.0, 0.0, 0.0));
  cloud.points.push_back(Vec3(0.0, 1.0, 0.0));
  return cloud;
}

void BM_DenseClusterTarget(benchmark::State& state) {
  const PointCloud cloud = IdenticalCluster();
  const bool cancel = state.range(0) == 1;
  for (auto _ : state) {
    bool asked = false;
    auto built = Target::Build(cloud, {}, [&] {
      if (!cancel) return false;
      const bool stop = asked;  // the first question starts the clock, the next says stop
      asked = true;
      return stop;
    });
    benchmark::DoNotOptimize(built);
  }
  state.SetLabel(cancel ? "cancelled at once" : "full build");
}
BENCHMARK(BM_DenseClusterTarget)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// The same cluster as a source of 40,000 samples against the bunny target: one MLS-SICP
// iteration's preprocessing and matching, or (argument 1) cancelled at the first question.
void BM_DenseClusterSource(benchmark::State& state) {
  const BunnyPair& p = Pair();
  const PointCloud source = IdenticalCluster();
  RegistrationOptions options;
  options.method = Method::kMlsSicp;
  options.num_samples = 40'000;
  options.max_iterations = 1;
  const bool cancel = state.range(0) == 1;
  for (auto _ : state) {
    RegistrationCallbacks callbacks;
    callbacks.should_stop = [&] { return cancel; };
    benchmark::DoNotOptimize(Register(*p.target, source, Matrix4::Identity(), options, callbacks));
  }
  state.SetLabel(cancel ? "cancelled at once" : "one iteration");
}
BENCHMARK(BM_DenseClusterSource)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// ---- many scans into one frame
// The three bundled bunny scans (bun315, bun000, bun045: 40k points each) in bun000's frame by
// data/bunny/pairs.csv, the first and last turned by 5 degrees and moved by 5 d.
struct BunnyViews {
  std::vector<PointCloud> scans;
  std::vector<Matrix4> truth, start;
  double d = 0.0;
};

const BunnyViews& Views() {
  static const BunnyViews views = [] {
    BunnyViews v;
    const std::string dir = std::string(MLSREG_SOURCE_DIR) + "/data/bunny/";
    auto manifest = ReadManifest(dir + "pairs.csv");
    Matrix4 bun000_to_bun045 = Matrix4::Identity(), bun315_to_bun000 = Matrix4::Identity();
    for (const ManifestProblem& p : manifest->problems) {
      (p.id == "bun000_bun045" ? bun000_to_bun045 : bun315_to_bun000) = *p.ground_truth;
    }
    for (const char* name : {"bun315.ply", "bun000.ply", "bun045.ply"}) {
      v.scans.push_back(*ReadPointCloud(dir + name));
    }
    v.truth = {bun315_to_bun000, Matrix4::Identity(), bun000_to_bun045.inverse()};
    v.d = Pair().target->sampling_distance();
    for (std::size_t i = 0; i < v.truth.size(); ++i) {
      v.start.push_back(i == 1
                            ? v.truth[i]
                            : RandomPerturbation(5.0, 5.0 * v.d, Vec3::Zero(), 3 + i) * v.truth[i]);
    }
    return v;
  }();
  return views;
}

// AlignScans over the three views, sequential pairs (2 MLS-SICP edges), anchor bun000: the
// three target builds, the edges (argument: threads) and the pose graph. Compare with
// BM_TargetBuild/0 and BM_Registration/2 of the same run.
void BM_AlignScans(benchmark::State& state) {
  const BunnyViews& v = Views();
  AlignOptions options;
  options.pairs = PairPolicy::kSequential;
  options.initial_poses = v.start;
  options.anchor = 1;
  options.threads = static_cast<int>(state.range(0));
  double graph_iterations = 0;
  for (auto _ : state) {
    auto result = AlignScans(v.scans, options);
    graph_iterations = result->graph_iterations;
    benchmark::DoNotOptimize(result);
  }
  state.counters["graph_iterations"] = graph_iterations;
}
BENCHMARK(BM_AlignScans)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// The three views merged under their true poses (120k points), resampled onto the joint MLS
// surface, one point per voxel of d, on one thread. Counter points: the resampled cloud's.
void BM_ResampleMerged(benchmark::State& state) {
  const BunnyViews& v = Views();
  const PointCloud merged = MergeScans(v.scans, v.truth);
  std::size_t points = 0;
  for (auto _ : state) {
    auto resampled = ResampleOnMlsSurface(merged, v.d);
    points = resampled->cloud.size();
    benchmark::DoNotOptimize(resampled);
  }
  state.counters["points"] = static_cast<double>(points);
}
BENCHMARK(BM_ResampleMerged)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace mlsreg

BENCHMARK_MAIN();
