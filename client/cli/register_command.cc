#include <cstdio>
#include <fstream>
#include <memory>
#include <optional>
#include <string>

#include "cli/commands.h"
#include "cli/registration_flags.h"
#include "cli/report.h"
#include "mlsreg/io.h"
#include "mlsreg/metrics.h"

namespace mlsreg::cli {
namespace {

struct RegisterArgs {
  std::string source, target, init, gt, json;
  bool quiet = false;
  double perturb_angle = 0.0, perturb_translation = 0.0;
  std::uint64_t perturb_seed = 1;
  RegistrationFlags flags;
};

int Fail(const absl::Status& status) {
  std::fprintf(stderr, "mlsreg register: %s\n", std::string(status.message()).c_str());
  return status.code() == absl::StatusCode::kInvalidArgument ? 2 : 1;
}

int RunRegister(const RegisterArgs& args) {
  auto options = args.flags.ToOptions();
  if (!options.ok()) return Fail(options.status());
  Matrix4 initial = Matrix4::Identity();
  if (!args.init.empty()) {
    auto m = ParseTransform(args.init, "--init");
    if (!m.ok()) return Fail(m.status());
    initial = *m;
  }
  std::optional<Matrix4> truth;
  if (!args.gt.empty()) {
    auto m = ParseTransform(args.gt, "--gt");
    if (!m.ok()) return Fail(m.status());
    truth = *m;
  }
  auto source = ReadPointCloud(args.source);
  if (!source.ok()) return Fail(source.status());
  auto target_cloud = ReadPointCloud(args.target);
  if (!target_cloud.ok()) return Fail(target_cloud.status());
  auto target = Target::Build(*std::move(target_cloud));
  if (!target.ok()) return Fail(target.status());
  if (args.perturb_angle != 0.0 || args.perturb_translation != 0.0) {
    // Same protocol as `mlsreg eval`: rotate about the source centroid as placed by --init.
    Vec3 centroid = Vec3::Zero();
    for (const Vec3& p : source->points) centroid += p;
    centroid /= static_cast<double>(source->size());
    centroid = initial.topLeftCorner<3, 3>() * centroid + initial.topRightCorner<3, 1>();
    initial = RandomPerturbation(args.perturb_angle,
                                 args.perturb_translation * (*target)->sampling_distance(),
                                 centroid, args.perturb_seed) *
              initial;
  }
  if (!args.quiet) {
    std::printf("%s: source %zu points, target %zu points, d = %.6g, target prepared in %.3f s\n",
                std::string(MethodName(options->method)).c_str(), source->size(),
                (*target)->cloud().size(), (*target)->sampling_distance(),
                (*target)->build_seconds());
  }
  RegistrationCallbacks callbacks;
  if (!args.quiet) {
    callbacks.on_iteration = [](const IterationReport& r) {
      std::printf("%s\n", FormatIteration(r).c_str());
      std::fflush(stdout);
    };
  }
  auto result = Register(**target, *source, initial, *options, callbacks);
  if (!result.ok()) return Fail(result.status());
  std::optional<PoseError> error;
  if (truth) {
    error = EvaluatePose(source->points, result->transform, *truth, result->sampling_distance);
  }
  std::printf("%s", FormatResult(*result, error).c_str());
  if (!args.json.empty()) {
    std::ofstream out(args.json);
    out << ResultJson(MethodName(options->method), *result, error).dump(2) << "\n";
    if (!out) return Fail(absl::UnavailableError("cannot write --json file '" + args.json + "'"));
  }
  return 0;
}

}  // namespace

CommandRunner AddRegisterCommand(CLI::App& app) {
  auto args = std::make_shared<RegisterArgs>();
  CLI::App* cmd = app.add_subcommand("register", "register a source scan to a target scan");
  cmd->add_option("--source", args->source, "source cloud (PLY, PCD, XYZ/CSV)")->required();
  cmd->add_option("--target", args->target, "target cloud (PLY, PCD, XYZ/CSV)")->required();
  cmd->add_option("--init", args->init,
                  "initial source->target transform: 16 row-major numbers or a file");
  cmd->add_option("--gt", args->gt, "ground-truth transform, to report the error against");
  cmd->add_option("--json", args->json, "write the result (transform, trace, errors) as JSON");
  cmd->add_flag("--quiet", args->quiet, "print only the result");
  cmd->add_option("--perturb-angle", args->perturb_angle,
                  "rotate the start pose by this angle (degrees) about a seeded random axis");
  cmd->add_option("--perturb-translation", args->perturb_translation,
                  "and translate it by this many d in a seeded random direction");
  cmd->add_option("--perturb-seed", args->perturb_seed, "perturbation seed");
  args->flags.AddTo(*cmd);
  return [args] { return RunRegister(*args); };
}

}  // namespace mlsreg::cli
