// mlsreg: point-cloud registration with moving-least-squares correspondences in Sparse ICP.
#include <cstdio>
#include <vector>

#include "cli/commands.h"
#include "cli/exit_codes.h"

int main(int argc, char** argv) {
  CLI::App app{"mlsreg: rigid point-cloud registration with MLS correspondences in Sparse ICP",
               "mlsreg"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "mlsreg " MLSREG_VERSION);
  std::vector<std::pair<CLI::App*, mlsreg::cli::CommandRunner>> commands;
  auto add = [&](mlsreg::cli::CommandRunner (*adder)(CLI::App&)) {
    const std::size_t before = app.get_subcommands({}).size();
    mlsreg::cli::CommandRunner run = adder(app);
    commands.emplace_back(app.get_subcommands({})[before], std::move(run));
  };
  add(&mlsreg::cli::AddRegisterCommand);
  add(&mlsreg::cli::AddVerifyCommand);
  add(&mlsreg::cli::AddEvalCommand);
  add(&mlsreg::cli::AddServeCommand);
  add(&mlsreg::cli::AddTargetsCommand);
  add(&mlsreg::cli::AddBatchCommand);
  add(&mlsreg::cli::AddAlignCommand);
  add(&mlsreg::cli::AddHealthCommand);
  add(&mlsreg::cli::AddStatsCommand);
  add(&mlsreg::cli::AddManualCommand);
  add(&mlsreg::cli::AddCompletionCommand);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version end the parse with code 0; any other parse error (an unknown flag, a
    // value out of range, no command) is bad usage, the documented code 2, not CLI11's own.
    const int code = app.exit(e);
    return code == 0 ? mlsreg::cli::kExitOk : mlsreg::cli::kExitBadInput;
  }
  for (auto& [sub, run] : commands) {
    if (sub->parsed()) return run();
  }
  return mlsreg::cli::kExitBadInput;
}
