// `mlsreg verify`: whether a given transform lays the source on the target, by the verdict every
// registration reports (registration/verification.h), rival search included.
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>

#include "cli/commands.h"
#include "cli/exit_codes.h"
#include "cli/report.h"
#include "mlsreg/core/parallel_for.h"
#include "mlsreg/io/io.h"
#include "mlsreg/registration/registration.h"
#include "mlsreg/registration/verification.h"

namespace mlsreg::cli {
namespace {

struct VerifyArgs {
  std::string source, target, transform, json;
  int threads = HardwareThreads();
};

int RunVerify(const VerifyArgs& args) {
  auto transform = ParseTransform(args.transform, "--transform");
  if (!transform.ok()) return ExitFor("verify", transform.status());
  auto source = ReadPointCloud(args.source);
  if (!source.ok()) return ExitFor("verify", source.status());
  auto target_cloud = ReadPointCloud(args.target);
  if (!target_cloud.ok()) return ExitFor("verify", target_cloud.status());
  TargetOptions options;
  options.threads = args.threads;
  auto target = Target::Build(*std::move(target_cloud), options);
  if (!target.ok()) return ExitFor("verify", target.status());
  const PoseVerdict verdict =
      VerifyPoseSearchingRivals(**target, *source, *transform, args.threads);
  const VerificationScore& score = verdict.score;
  std::printf("%s\n", FormatVerification(score).c_str());
  if (verdict.rival) {
    std::printf("%s", FormatRival(*verdict.rival, score, Orthonormalize(*transform)).c_str());
  }
  if (!args.json.empty()) {
    nlohmann::json j = VerificationJson(score);
    if (verdict.rival) j["rival"] = RivalJson(*verdict.rival);
    std::ofstream out(args.json);
    out << j.dump(2) << "\n";
    if (!out)
      return ExitFor("verify",
                     absl::UnavailableError("cannot write --json file '" + args.json + "'"));
  }
  return score.verified() ? kExitOk : kExitNotVerified;
}

}  // namespace

CommandRunner AddVerifyCommand(CLI::App& app) {
  auto args = std::make_shared<VerifyArgs>();
  CLI::App* cmd = app.add_subcommand(
      "verify",
      "say whether a transform lays the source on the target (exit 0 verified, 4 not verified)");
  cmd->add_option("--source", args->source, "source cloud")->required();
  cmd->add_option("--target", args->target, "target cloud")->required();
  cmd->add_option("--transform", args->transform,
                  "the source->target transform to judge: 16 row-major numbers or a file")
      ->required();
  cmd->add_option("--json", args->json, "write the score as JSON");
  cmd->add_option("--threads", args->threads, "threads (the verdict is the same for any count)")
      ->check(CLI::Range(1, 256));
  return [args] { return RunVerify(*args); };
}

}  // namespace mlsreg::cli
