// `mlsreg targets ...`, `mlsreg health`, `mlsreg stats`: thin wrappers over the client library.
#include <cstdio>
#include <memory>
#include <string>

#include "absl/strings/str_format.h"
#include "cli/commands.h"
#include "cli/connection_flags.h"
#include "mlsreg/io/io.h"

namespace mlsreg::cli {
namespace {

int Fail(const char* command, const absl::Status& status) {
  std::fprintf(stderr, "mlsreg %s: %s: %s\n", command,
               absl::StatusCodeToString(status.code()).c_str(),
               std::string(status.message()).c_str());
  return status.code() == absl::StatusCode::kInvalidArgument ? 2 : 1;
}

void PrintTarget(const TargetInfo& t) {
  std::printf(
      "%-32s %-7s %10llu points  d = %-10.6g noise %.2f d %8.1f MiB  built in %.3f s  "
      "%llu registrations  "
      "%.23s%s\n",
      t.id.c_str(), std::string(NameOf(TargetStateNames(), t.state)).c_str(),
      static_cast<unsigned long long>(t.point_count), t.sampling_distance, t.noise_sigma_d,
      t.memory_bytes / 1048576.0, t.build_seconds, static_cast<unsigned long long>(t.registrations),
      t.digest.c_str(), t.has_intrinsics ? "  organised" : "");
}

struct TargetsArgs {
  ConnectionFlags connection;
  std::string id, file;
};

}  // namespace

CommandRunner AddTargetsCommand(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand("targets", "manage the targets cached by a server");
  cmd->require_subcommand(1);
  auto args = std::make_shared<TargetsArgs>();
  CLI::App* upload =
      cmd->add_subcommand("upload", "upload a cloud as a target: upload --id NAME FILE");
  upload->add_option("--id", args->id, "target id ([A-Za-z0-9._-], 1-128 chars)")->required();
  upload->add_option("file", args->file, "cloud file (PLY, PCD, XYZ/CSV)")->required();
  CLI::App* get = cmd->add_subcommand("get", "show one target");
  get->add_option("id", args->id, "target id")->required();
  CLI::App* list = cmd->add_subcommand("list", "list all targets");
  CLI::App* remove = cmd->add_subcommand("delete", "delete a target (admin)");
  remove->add_option("id", args->id, "target id")->required();
  for (CLI::App* sub : {upload, get, list, remove}) args->connection.AddTo(*sub, true);
  return [args, upload, get, list, remove]() -> int {
    auto client = args->connection.Connect();
    if (!client.ok()) return Fail("targets", client.status());
    if (upload->parsed()) {
      auto cloud = ReadPointCloud(args->file);
      if (!cloud.ok()) return Fail("targets upload", cloud.status());
      auto info = (*client)->UploadTarget(args->id, *cloud);
      if (!info.ok()) return Fail("targets upload", info.status());
      PrintTarget(*info);
    } else if (get->parsed()) {
      auto info = (*client)->GetTarget(args->id);
      if (!info.ok()) return Fail("targets get", info.status());
      PrintTarget(*info);
    } else if (list->parsed()) {
      auto all = (*client)->ListTargets();
      if (!all.ok()) return Fail("targets list", all.status());
      for (const TargetInfo& t : *all) PrintTarget(t);
      std::printf("%zu targets\n", all->size());
    } else if (remove->parsed()) {
      if (absl::Status s = (*client)->DeleteTarget(args->id); !s.ok()) {
        return Fail("targets delete", s);
      }
      std::printf("deleted %s\n", args->id.c_str());
    }
    return 0;
  };
}

CommandRunner AddHealthCommand(CLI::App& app) {
  CLI::App* cmd =
      app.add_subcommand("health", "ask servers whether they are serving (exit 0 if every one is)");
  auto connection = std::make_shared<ConnectionFlags>();
  connection->AddTo(*cmd, true);
  return [connection]() -> int {
    auto client = connection->Connect();
    if (!client.ok()) return Fail("health", client.status());
    const std::vector<std::string> replicas = (*client)->replicas();
    bool all_serving = true;
    for (std::size_t i = 0; i < replicas.size(); ++i) {
      auto health = (*client)->Health(i);
      if (!health.ok()) {
        Fail("health", health.status());
        all_serving = false;
        continue;
      }
      if (replicas.size() > 1) std::printf("%s ", replicas[i].c_str());
      std::printf("%s\n", health->status.c_str());
      all_serving = all_serving && health->serving;
    }
    return all_serving ? 0 : 1;
  };
}

CommandRunner AddStatsCommand(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand("stats", "print servers' counters and latencies (JSON)");
  auto connection = std::make_shared<ConnectionFlags>();
  connection->AddTo(*cmd, true);
  return [connection]() -> int {
    auto client = connection->Connect();
    if (!client.ok()) return Fail("stats", client.status());
    const std::vector<std::string> replicas = (*client)->replicas();
    for (std::size_t i = 0; i < replicas.size(); ++i) {
      auto json = (*client)->StatsJson(i);
      if (!json.ok()) return Fail("stats", json.status());
      if (replicas.size() > 1) std::printf("== %s\n", replicas[i].c_str());
      std::printf("%s\n", json->c_str());
    }
    return 0;
  };
}

}  // namespace mlsreg::cli
