#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "cli/cloud_files.h"
#include "cli/commands.h"
#include "cli/connection_flags.h"
#include "cli/convergence_plot.h"
#include "cli/exit_codes.h"
#include "cli/registration_flags.h"
#include "cli/report.h"
#include "cli/result_clouds.h"
#include "mlsreg/core/parallel_for.h"
#include "mlsreg/evaluation/evaluation.h"
#include "mlsreg/evaluation/metrics.h"
#include "mlsreg/io/io.h"

namespace mlsreg::cli {
namespace {

struct RegisterArgs {
  std::string source, target, init, gt, json, aligned, merged, plot;
  std::vector<std::string> columns;  // of text and .npy clouds
  bool quiet = false;
  double perturb_angle = 0.0, perturb_translation = 0.0;
  std::uint64_t perturb_seed = 1;
  int threads = HardwareThreads();
  RegistrationFlags flags;
  ConnectionFlags connection;
};

void PrintIteration(const IterationReport& r) {
  std::printf("%s\n", FormatIteration(r).c_str());
  std::fflush(stdout);
}

Matrix4 Perturbed(const RegisterArgs& args, const PointCloud& source, const Matrix4& initial,
                  double d) {
  // The protocol of `mlsreg eval`, problem 0.
  return PerturbedStart(source, initial, d,
                        {args.perturb_angle, args.perturb_translation, args.perturb_seed});
}

// Writes --json, then --plot (a picture that fails loses no result), and returns the exit code
// of a finished registration.
int Finish(const RegisterArgs& args, const RegistrationOptions& options,
           const RegistrationResult& result, const std::optional<PoseError>& error,
           const PointCloud& source, const std::optional<Matrix4>& truth) {
  if (!args.json.empty()) {
    std::ofstream out(args.json);
    out << ResultJson(MethodName(options.method), result, error).dump(2) << "\n";
    if (!out)
      return ExitFor("register",
                     absl::UnavailableError("cannot write --json file '" + args.json + "'"));
  }
  if (!args.plot.empty()) {
    if (absl::Status s =
            WriteConvergencePlot(args.plot, MethodName(options.method), result, source, truth);
        !s.ok()) {
      return ExitFor("register", s);
    }
  }
  if (result.verification && !result.verification->verified() &&
      result.termination != Termination::kCancelled) {
    return kExitNotVerified;
  }
  return 0;
}

// --server: the target is a cached target id; the registration streams from the server.
int RunRemote(const RegisterArgs& args, const RegistrationOptions& options,
              const PointCloud& source, Matrix4 initial, const std::optional<Matrix4>& truth) {
  auto client = args.connection.Connect();
  if (!client.ok()) return ExitFor("register", client.status());
  if (args.perturb_angle != 0.0 || args.perturb_translation != 0.0) {
    auto target = (*client)->GetTarget(args.target);
    if (!target.ok()) return ExitFor("register", target.status());
    initial = Perturbed(args, source, initial, target->sampling_distance);
  }
  if (!args.quiet) {
    std::printf("%s via %s: source %zu points, target '%s'\n",
                std::string(MethodName(options.method)).c_str(),
                args.connection.options().address.c_str(), source.size(), args.target.c_str());
  }
  std::function<void(const IterationReport&)> on_progress;
  if (!args.quiet) on_progress = PrintIteration;
  auto remote = (*client)->Register(args.target, source, initial, options, truth, on_progress);
  if (!remote.ok()) return ExitFor("register", remote.status());
  std::printf(
      "%s",
      FormatResult(remote->result, remote->ground_truth_error, options.max_iterations).c_str());
  return Finish(args, options, remote->result, remote->ground_truth_error, source, truth);
}

// With --server, --target names a target on the server. A path there is a mistake the server
// would answer with "character 0 is not allowed"; say what to do instead.
absl::Status CheckServedTarget(const RegisterArgs& args) {
  std::error_code error;
  const bool looks_like_a_file = args.target.find('/') != std::string::npos ||
                                 CloudFormatOfPath(args.target).ok() ||
                                 std::filesystem::is_regular_file(args.target, error);
  if (!looks_like_a_file) return absl::OkStatus();
  return absl::InvalidArgumentError(absl::StrCat(
      "--target: with --server, the target is the id of a target on the server, not a file ('",
      args.target, "'); upload the file first with `mlsreg targets upload --server ",
      args.connection.options().address, " --id NAME ", args.target,
      "` and register with --target NAME (`mlsreg targets list` shows the ids)"));
}

// The flags naming files are checked before anything runs: a registration is not lost to a typo.
absl::Status CheckArguments(const RegisterArgs& args) {
  std::vector<std::string> inputs = {args.source};
  if (!args.connection.has_server()) inputs.push_back(args.target);
  if (absl::Status s = CheckColumnsApply(args.columns, inputs); !s.ok()) return s;
  for (const auto& [flag, path] :
       {std::pair{"--aligned", &args.aligned}, std::pair{"--merged", &args.merged}}) {
    if (path->empty()) continue;
    if (absl::Status s = CheckCloudOutput(flag, *path); !s.ok()) return s;
  }
  if (!args.json.empty()) {
    if (absl::Status s = CheckWritable("--json", args.json); !s.ok()) return s;
  }
  if (!args.plot.empty()) {
    if (absl::Status s = CheckPlotPath(args.plot); !s.ok()) return s;
  }
  if (args.connection.has_server()) return CheckServedTarget(args);
  return absl::OkStatus();
}

int RunRegister(const RegisterArgs& args) {
  auto options = args.flags.ToOptions();
  if (!options.ok()) return ExitFor("register", options.status());
  if (absl::Status s = CheckArguments(args); !s.ok()) return ExitFor("register", s);
  Matrix4 initial = Matrix4::Identity();
  if (!args.init.empty()) {
    auto m = ParseTransform(args.init, "--init");
    if (!m.ok()) return ExitFor("register", m.status());
    initial = *m;
  }
  std::optional<Matrix4> truth;
  if (!args.gt.empty()) {
    auto m = ParseTransform(args.gt, "--gt");
    if (!m.ok()) return ExitFor("register", m.status());
    truth = *m;
  }
  auto source = ReadCloudNoting("register", args.source, args.columns);
  if (!source.ok()) return ExitFor("register", source.status());
  if (args.connection.has_server()) {
    if (!args.aligned.empty() || !args.merged.empty()) {
      return ExitFor(
          "register",
          absl::InvalidArgumentError(
              "--aligned and --merged need the target's cloud: register locally (no --server)"));
    }
    return RunRemote(args, *options, *source, initial, truth);
  }
  auto target_cloud = ReadCloudNoting("register", args.target, args.columns);
  if (!target_cloud.ok()) return ExitFor("register", target_cloud.status());
  TargetOptions target_options;
  target_options.threads = args.threads;
  auto target = Target::Build(*std::move(target_cloud), target_options);
  if (!target.ok()) return ExitFor("register", target.status());
  initial = Perturbed(args, *source, initial, (*target)->sampling_distance());
  if (!args.quiet) {
    std::printf("%s: source %zu points, target %zu points, d = %.6g, target prepared in %.3f s\n",
                std::string(MethodName(options->method)).c_str(), source->size(),
                (*target)->cloud().size(), (*target)->sampling_distance(),
                (*target)->build_seconds());
  }
  RegistrationCallbacks callbacks;
  if (!args.quiet) callbacks.on_iteration = PrintIteration;
  auto result =
      Register(**target, *source, initial, *options, callbacks, ExecutionOptions{args.threads});
  if (!result.ok()) return ExitFor("register", result.status());
  std::optional<PoseError> error;
  if (truth) {
    error = EvaluatePose(source->points, result->transform, *truth, result->sampling_distance);
  }
  std::printf("%s", FormatResult(*result, error, options->max_iterations).c_str());
  if (!args.aligned.empty()) {
    if (absl::Status s = WriteAlignedCloud(args.aligned, *source, result->transform, **target);
        !s.ok()) {
      return ExitFor("register", s);
    }
  }
  if (!args.merged.empty()) {
    if (absl::Status s = WriteMergedCloud(args.merged, *source, result->transform, **target);
        !s.ok()) {
      return ExitFor("register", s);
    }
  }
  return Finish(args, *options, *result, error, *source, truth);
}

}  // namespace

CommandRunner AddRegisterCommand(CLI::App& app) {
  auto args = std::make_shared<RegisterArgs>();
  CLI::App* cmd = app.add_subcommand(
      "register",
      "register a source scan to a target scan (exit codes: see `mlsreg manual`; 4: method auto "
      "found no pose that verifies)");
  cmd->add_option("--source", args->source, "source cloud (PLY, PCD, XYZ/CSV, NPY)")->required();
  cmd->add_option("--target", args->target,
                  "target cloud (PLY, PCD, XYZ/CSV, NPY), or with --server the id of a target on "
                  "the server (upload one with `mlsreg targets upload`)")
      ->required();
  AddColumnsFlag(*cmd, &args->columns);
  cmd->add_option("--init", args->init,
                  "initial source->target transform: 16 row-major numbers or a file");
  cmd->add_option("--gt", args->gt, "ground-truth transform, to report the error against");
  cmd->add_option("--json", args->json, "write the result (transform, trace, errors) as JSON");
  cmd->add_flag("--quiet", args->quiet, "print only the result");
  cmd->add_option("--aligned", args->aligned,
                  "write the aligned source (PLY, PCD, XYZ/CSV or NPY by the extension) with its "
                  "distance to the target's MLS surface as scalar field distance_d (units of d), "
                  "and the source's colours, or if it has none the distance as colours (blue 0, "
                  "red >= 3 d); NPY columns: x y z [nx ny nz] distance_d r g b");
  cmd->add_option("--merged", args->merged,
                  "write source (orange) and target (blue) in the target's frame (PLY, PCD, "
                  "XYZ/CSV or NPY by the extension), with scalar field cloud (0 source, 1 "
                  "target); NPY columns: x y z cloud r g b");
  cmd->add_option("--plot", args->plot,
                  "draw the convergence as PNG: RMSE/d per iteration (and against --gt), matched "
                  "and rejected correspondences (needs python3-matplotlib)");
  cmd->add_option("--perturb-angle", args->perturb_angle,
                  "rotate the start pose by this angle (degrees) about a seeded random axis");
  cmd->add_option("--perturb-translation", args->perturb_translation,
                  "and translate it by this many d in a seeded random direction");
  cmd->add_option("--perturb-seed", args->perturb_seed, "perturbation seed");
  cmd->add_option("--threads", args->threads,
                  "threads of the target build and the registration (default: all cores; the "
                  "result is the same for any count; with --server the server decides)")
      ->check(CLI::Range(1, 256));
  args->flags.AddTo(*cmd);
  args->connection.AddTo(*cmd, /*server_required=*/false);
  return [args] { return RunRegister(*args); };
}

}  // namespace mlsreg::cli
