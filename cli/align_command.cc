// `mlsreg align`: many scans into one frame. Pairwise registrations (MLS-SICP by default) along
// the chosen pairs, one progress line per edge, then a pose graph; prints the edges and the
// poses, writes the poses (rows or Stanford .conf) and optionally the merged cloud.
#include <cstdio>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <tuple>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "cli/cloud_files.h"
#include "cli/commands.h"
#include "cli/connection_flags.h"
#include "cli/exit_codes.h"
#include "cli/registration_flags.h"
#include "cli/report.h"
#include "mlsreg/core/length.h"
#include "mlsreg/core/parallel_for.h"
#include "mlsreg/evaluation/metrics.h"
#include "mlsreg/io/io.h"
#include "mlsreg/io/pose_files.h"
#include "mlsreg/multiview/align_scans.h"

namespace mlsreg::cli {
namespace {

struct AlignArgs {
  std::vector<std::string> scans;
  std::string poses, gt, out, merged, json, pairs = "loop";
  double min_overlap = AlignOptions().min_overlap;
  // Lengths as given ("20", "20d", "5m"), parsed with the other flags.
  std::string overlap_distance = "20", resample_spacing = "1", resample_radius = "0";
  int anchor = 0;
  int threads = HardwareThreads();
  bool cached = false;      // with --server: --scans are ids of targets on the server
  bool resample = false;    // --merged onto the joint MLS surface
  RegistrationFlags flags;  // edges by method auto, as registrations
  ConnectionFlags connection;
};

std::string Name(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

nlohmann::json Row(const Matrix4& m) {
  std::vector<double> v;
  for (int k = 0; k < 16; ++k) v.push_back(m(k / 4, k % 4));
  return v;
}

int RunAlign(const AlignArgs& args) {
  auto edge_options = args.flags.ToOptions();
  if (!edge_options.ok()) return ExitFor("align", edge_options.status());
  auto policy = ParseEnum<PairPolicy>(PairPolicyNames(), args.pairs, "--pairs");
  if (!policy.ok()) return ExitFor("align", policy.status());
  const auto overlap_distance = ParseLength(args.overlap_distance, "--overlap-distance");
  if (!overlap_distance.ok()) return ExitFor("align", overlap_distance.status());
  SurfaceResampling resampling;
  for (const auto& [flag, text, length] :
       {std::tuple{"--resample-spacing", &args.resample_spacing, &resampling.spacing},
        std::tuple{"--resample-radius", &args.resample_radius, &resampling.radius}}) {
    auto parsed = ParseLength(*text, flag);
    if (!parsed.ok()) return ExitFor("align", parsed.status());
    *length = *parsed;
  }
  const bool remote = args.connection.has_server();
  if (args.cached && !remote) {
    return ExitFor("align",
                   absl::InvalidArgumentError("--cached names targets on a server: give --server"));
  }
  if (args.resample && args.merged.empty()) {
    return ExitFor("align", absl::InvalidArgumentError(
                                "--resample resamples the --merged cloud: give --merged"));
  }
  if (args.cached && (!args.merged.empty() || !args.gt.empty())) {
    return ExitFor("align",
                   absl::InvalidArgumentError(
                       "--merged and --gt need the scans' clouds: give files, not --cached ids"));
  }
  if (!args.merged.empty()) {
    if (absl::Status s = CheckCloudOutput("--merged", args.merged); !s.ok())
      return ExitFor("align", s);
  }
  for (const auto& [flag, path] :
       {std::pair{"--out", &args.out}, std::pair{"--json", &args.json}}) {
    if (path->empty()) continue;
    if (absl::Status s = CheckWritable(flag, *path); !s.ok()) return ExitFor("align", s);
  }
  std::vector<PointCloud> scans;
  for (const std::string& path : args.cached ? std::vector<std::string>{} : args.scans) {
    auto cloud = ReadCloudNoting("align", path);
    if (!cloud.ok()) return ExitFor("align", cloud.status());
    scans.push_back(*std::move(cloud));
  }
  AlignOptions options;
  options.edge = *edge_options;
  options.pairs = *policy;
  options.min_overlap = args.min_overlap;
  options.overlap_distance = *overlap_distance;
  options.anchor = args.anchor;
  options.threads = std::max(1, args.threads);
  if (!args.poses.empty()) {
    auto poses = ReadPoses(args.poses, args.scans);
    if (!poses.ok()) return ExitFor("align", poses.status());
    options.initial_poses = *std::move(poses);
  }
  std::vector<Matrix4> truth;
  if (!args.gt.empty()) {
    auto poses = ReadPoses(args.gt, args.scans);
    if (!poses.ok()) return ExitFor("align", poses.status());
    truth = *std::move(poses);
  }
  if (remote) {
    std::printf("align: %zu scans on %s, pairs %s, edges by %s\n", args.scans.size(),
                args.connection.options().address.c_str(), args.pairs.c_str(),
                std::string(MethodName(options.edge.method)).c_str());
  } else {
    std::printf("align: %zu scans, pairs %s, edges by %s, %d threads\n", scans.size(),
                args.pairs.c_str(), std::string(MethodName(options.edge.method)).c_str(),
                options.threads);
  }
  const auto print_edge = [&](const AlignEdge& e, int done, int total) {
    std::printf(
        "[edge %d/%d] %s <- %s: %s after %d iterations, rmse %.3f d, overlap %.1f %%\n", done,
        total, Name(args.scans[e.from]).c_str(), Name(args.scans[e.to]).c_str(),
        std::string(TerminationName(e.registration.termination)).c_str(), e.registration.iterations,
        e.registration.trace.empty() ? 0.0 : e.registration.trace.back().rmse_d, 100.0 * e.overlap);
    std::fflush(stdout);
  };
  absl::StatusOr<AlignResult> result;
  if (remote) {
    auto client = args.connection.Connect();
    if (!client.ok()) return ExitFor("align", client.status());
    std::vector<client::RemoteScan> remote_scans;
    for (std::size_t i = 0; i < args.scans.size(); ++i) {
      client::RemoteScan scan;
      if (args.cached) {
        scan.target_id = args.scans[i];
      } else {
        scan.cloud = std::make_shared<const PointCloud>(scans[i]);
      }
      remote_scans.push_back(std::move(scan));
    }
    auto aligned = (*client)->AlignScans(remote_scans, options, print_edge);
    if (!aligned.ok()) return ExitFor("align", aligned.status());
    std::printf("request %s, queued %.3f s\n", aligned->request_id.c_str(), aligned->queue_seconds);
    result = std::move(aligned->result);
  } else {
    AlignCallbacks callbacks;
    callbacks.on_edge = print_edge;
    result = AlignScans(scans, options, callbacks);
  }
  if (!result.ok()) return ExitFor("align", result.status());

  std::printf("\nedges (disagreement with the optimised poses, units of d = %.6g):\n",
              result->sampling_distance);
  std::printf("  %-24s %-24s %8s %8s %8s %6s\n", "target", "source", "overlap", "before", "after",
              "kept");
  for (const AlignEdge& e : result->edges) {
    std::printf("  %-24s %-24s %7.1f%% %8.3f %8.3f %6s\n", Name(args.scans[e.from]).c_str(),
                Name(args.scans[e.to]).c_str(), 100.0 * e.overlap, e.residual_before_d,
                e.residual_after_d, e.kept ? "yes" : (e.trusted ? "NO" : "NO (not verified)"));
  }
  if (options.pairs == PairPolicy::kLoop) {
    std::printf("loop closure of the chained edges: %.3f deg, %.3f d%s\n",
                result->loop_closure_rotation_deg, result->loop_closure_error_d,
                result->loop_closure_exceeded
                    ? absl::StrFormat("  WARNING: beyond %.3g deg or %.3g d: an edge is wrong",
                                      options.max_loop_closure_deg, options.max_loop_closure_d)
                          .c_str()
                    : "");
  }
  // Ground truth in the anchor's frame, as the result.
  std::vector<double> rotation_error, translation_error;
  if (!truth.empty()) {
    const Matrix4 to_anchor = truth[args.anchor].inverse();
    for (std::size_t i = 0; i < truth.size(); ++i) {
      const Matrix4 expected = to_anchor * truth[i];
      const PoseError error =
          EvaluatePose(scans[i].points, result->poses[i], expected, result->sampling_distance);
      rotation_error.push_back(error.rotation_deg);
      translation_error.push_back(error.translation_d);
    }
  }
  std::printf(
      "\nposes (scan -> frame of %s, row-major; graph sigma: 1 sigma of the least certain rotation "
      "and of the scan origin's least certain translation as the graph propagates its edges' "
      "covariances, counting the noise that edges sharing a scan share: a ranking, and an "
      "estimate within 0.7-2x of the errors' spread on synthetic streets, docs/scenes.md)\n",
      Name(args.scans[args.anchor]).c_str());
  for (std::size_t i = 0; i < result->poses.size(); ++i) {
    std::printf("  %-24s", Name(args.scans[i]).c_str());
    for (int k = 0; k < 12; ++k) std::printf(" %10.6f", result->poses[i](k / 4, k % 4));
    std::printf("   drift removed %.3f d", result->chain_deviation_d[i]);
    if (i < result->pose_covariances.size() && result->pose_covariances[i]) {
      const PoseSigmas sigmas = SigmasOf(*result->pose_covariances[i]);
      std::printf("   graph sigma %.3f deg %.3g", sigmas.rotation_deg, sigmas.translation);
    }
    if (!truth.empty()) {
      std::printf("   vs gt %.3f deg %.3f d", rotation_error[i], translation_error[i]);
    }
    std::printf("\n");
  }
  std::printf(
      "aligned in %.2f s (%d pose-graph iterations; the final solve weighed %d kept edges by "
      "their pose covariance)\n",
      result->seconds, result->graph_iterations, result->covariance_weighted_edges);
  if (!args.out.empty()) {
    if (absl::Status s = WritePoses(args.out, result->poses, args.scans); !s.ok())
      return ExitFor("align", s);
  }
  if (!args.merged.empty()) {
    PointCloud merged = MergeScans(scans, result->poses);
    if (args.resample) {
      resampling.threads = std::max(1, args.threads);
      auto resampled = ResampleOnMlsSurface(merged, result->sampling_distance, resampling);
      if (!resampled.ok()) return ExitFor("align", resampled.status());
      std::printf(
          "merged cloud resampled onto the joint MLS surface: %zu points of %zu (radius %.1f d, "
          "noise %.2f d, %d dropped) in %.2f s\n",
          resampled->cloud.size(), merged.size(), resampled->radius_d, resampled->noise_sigma_d,
          resampled->dropped, resampled->seconds);
      merged = std::move(resampled->cloud);
    }
    if (absl::Status s = WritePointCloud(merged, args.merged); !s.ok()) return ExitFor("align", s);
  }
  if (!args.json.empty()) {
    nlohmann::json j;
    j["sampling_distance"] = result->sampling_distance;
    j["pairs"] = args.pairs;
    j["method"] = std::string(MethodName(options.edge.method));
    j["loop_closure_rotation_deg"] = result->loop_closure_rotation_deg;
    j["loop_closure_error_d"] = result->loop_closure_error_d;
    j["loop_closure_exceeded"] = result->loop_closure_exceeded;
    j["unverified_scans"] = nlohmann::json::array();
    for (int i : result->unverified_scans) j["unverified_scans"].push_back(args.scans[i]);
    j["seconds"] = result->seconds;
    j["covariance_weighted_edges"] = result->covariance_weighted_edges;
    for (std::size_t i = 0; i < result->poses.size(); ++i) {
      nlohmann::json scan = {{"scan", args.scans[i]},
                             {"pose", Row(result->poses[i])},
                             {"chained_pose", Row(result->chained_poses[i])},
                             {"drift_removed_d", result->chain_deviation_d[i]},
                             {"pose_covariance", nullptr}};
      if (i < result->pose_covariances.size() && result->pose_covariances[i]) {
        scan["pose_covariance"] = PoseCovarianceJson(result->pose_covariances[i]);
        const PoseSigmas sigmas = SigmasOf(*result->pose_covariances[i]);
        scan["pose_rotation_sigma_deg"] = sigmas.rotation_deg;
        scan["pose_translation_sigma"] = sigmas.translation;
      }
      if (!truth.empty()) {
        scan["rotation_error_deg"] = rotation_error[i];
        scan["translation_error_d"] = translation_error[i];
      }
      j["scans"].push_back(scan);
    }
    for (const AlignEdge& e : result->edges) {
      j["edges"].push_back(
          {{"from", e.from},
           {"to", e.to},
           {"relative", Row(e.relative)},
           {"termination", std::string(TerminationName(e.registration.termination))},
           {"iterations", e.registration.iterations},
           {"overlap", e.overlap},
           {"correspondences", e.correspondences},
           {"residual_before_d", e.residual_before_d},
           {"residual_after_d", e.residual_after_d},
           {"trusted", e.trusted},
           {"kept", e.kept},
           {"verification", VerificationJson(e.verification)}});
    }
    std::ofstream out(args.json);
    out << j.dump(2) << "\n";
    if (!out)
      return ExitFor("align",
                     absl::UnavailableError("cannot write --json file '" + args.json + "'"));
  }
  if (!result->unverified_scans.empty()) {
    std::string names;
    for (int i : result->unverified_scans) absl::StrAppend(&names, " ", Name(args.scans[i]));
    std::fprintf(stderr,
                 "mlsreg align: NOT VERIFIED: no chain of verified edges joins these scans to %s; "
                 "do not trust their poses:%s\n",
                 Name(args.scans[args.anchor]).c_str(), names.c_str());
    return kExitNotVerified;
  }
  return 0;
}

}  // namespace

CommandRunner AddAlignCommand(CLI::App& app) {
  auto args = std::make_shared<AlignArgs>();
  CLI::App* cmd = app.add_subcommand(
      "align", "align many scans into one frame: pairwise registrations and a pose graph");
  cmd->add_option("--scans", args->scans,
                  "the scans (PLY, PCD, XYZ/CSV, NPY), in order; with --server --cached, "
                  "target ids")
      ->required()
      ->expected(2, -1);
  cmd->add_option("--poses", args->poses,
                  "initial poses (scan -> common frame): a .conf (Stanford bmesh lines, "
                  "rotation R(q)^T) or 16 row-major numbers per line in scan order; default: "
                  "identity");
  cmd->add_option("--pairs", args->pairs,
                  "sequential | loop (sequential + last->first) | overlap (every pair "
                  "overlapping under the initial poses)")
      ->capture_default_str();
  cmd->add_option("--min-overlap", args->min_overlap,
                  "--pairs overlap: share of a scan within --overlap-distance of the other "
                  "(under the initial poses) to pair them")
      ->capture_default_str();
  cmd->add_option("--overlap-distance", args->overlap_distance,
                  "--pairs overlap: that distance, units of d, or a length: 5m, 30cm, 5mm")
      ->type_name("LENGTH")
      ->capture_default_str();
  cmd->add_option("--anchor", args->anchor, "the scan whose frame the poses are in")
      ->capture_default_str();
  cmd->add_option("--gt", args->gt, "ground-truth poses (same formats), to report pose errors");
  cmd->add_option("--out", args->out, "write the poses: .conf (Stanford) or rows (any other name)");
  cmd->add_option("--merged", args->merged, "write every scan in the anchor's frame as one cloud");
  cmd->add_flag("--resample", args->resample,
                "with --merged: resample the merged cloud onto the joint MLS surface of all scans "
                "(one point per voxel, no layers where scans overlap, noise smoothed)");
  cmd->add_option("--resample-spacing", args->resample_spacing,
                  "--resample: the voxel edge, units of d, or a length: 1m, 30cm, 5mm")
      ->type_name("LENGTH")
      ->capture_default_str();
  cmd->add_option("--resample-radius", args->resample_radius,
                  "--resample: MLS support radius, units of d, or a length: 1m, 30cm, 5mm (0: "
                  "from the merged cloud's noise)")
      ->type_name("LENGTH")
      ->capture_default_str();
  cmd->add_option("--json", args->json, "write poses, edges and errors as JSON");
  cmd->add_option("--threads", args->threads,
                  "edges registered at once (with --server the server decides)")
      ->capture_default_str();
  cmd->add_flag("--cached", args->cached,
                "with --server: the --scans are ids of targets cached on the server (else the "
                "files are uploaded with the call)");
  args->flags.AddTo(*cmd);
  args->connection.AddTo(*cmd, /*server_required=*/false);
  return [args] { return RunAlign(*args); };
}

}  // namespace mlsreg::cli
