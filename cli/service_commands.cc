// `mlsreg targets ...`, `mlsreg health`, `mlsreg stats`: thin wrappers over the client library.
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "absl/strings/str_format.h"
#include "cli/cloud_files.h"
#include "cli/commands.h"
#include "cli/connection_flags.h"
#include "cli/exit_codes.h"
#include "mlsreg/io/io.h"

namespace mlsreg::cli {
namespace {

int ServiceFail(const char* command, const absl::Status& status) {
  std::fprintf(stderr, "mlsreg %s: %s: %s\n", command,
               absl::StatusCodeToString(status.code()).c_str(),
               std::string(status.message()).c_str());
  return status.code() == absl::StatusCode::kInvalidArgument ? kExitBadInput : kExitFailed;
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

nlohmann::json TargetJson(const TargetInfo& t) {
  return {{"id", t.id},
          {"state", std::string(NameOf(TargetStateNames(), t.state))},
          {"points", t.point_count},
          {"memory_bytes", t.memory_bytes},
          {"sampling_distance", t.sampling_distance},
          {"noise_sigma_d", t.noise_sigma_d},
          {"build_seconds", t.build_seconds},
          {"registrations", t.registrations},
          {"organised", t.has_intrinsics},
          {"content_digest", t.digest}};
}

struct TargetsArgs {
  ConnectionFlags connection;
  std::string id, file;
  std::vector<std::string> columns;  // of a text or .npy file
  bool json = false;                 // print JSON instead of text
};

}  // namespace

CommandRunner AddTargetsCommand(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand("targets", "manage the targets cached by a server");
  cmd->require_subcommand(1);
  auto args = std::make_shared<TargetsArgs>();
  CLI::App* upload =
      cmd->add_subcommand("upload", "upload a cloud as a target: upload --id NAME FILE");
  upload->add_option("--id", args->id, "target id ([A-Za-z0-9._-], 1-128 chars)")->required();
  upload->add_option("file", args->file, "cloud file (PLY, PCD, XYZ/CSV, NPY)")->required();
  AddColumnsFlag(*upload, &args->columns);
  CLI::App* get = cmd->add_subcommand("get", "show one target");
  get->add_option("id", args->id, "target id")->required();
  CLI::App* list = cmd->add_subcommand("list", "list all targets");
  CLI::App* remove = cmd->add_subcommand("delete", "delete a target (admin)");
  remove->add_option("id", args->id, "target id")->required();
  for (CLI::App* sub : {upload, get, list, remove}) args->connection.AddTo(*sub, true);
  for (CLI::App* sub : {upload, get, list}) {
    sub->add_flag("--json", args->json, "print the target(s) as JSON");
  }
  return [args, upload, get, list, remove]() -> int {
    auto client = args->connection.Connect();
    if (!client.ok()) return ServiceFail("targets", client.status());
    if (upload->parsed()) {
      if (absl::Status s = CheckColumnsApply(args->columns, {args->file}); !s.ok()) {
        return ServiceFail("targets upload", s);
      }
      auto cloud = ReadCloudNoting("targets upload", args->file, args->columns);
      if (!cloud.ok()) return ServiceFail("targets upload", cloud.status());
      auto info = (*client)->UploadTarget(args->id, *cloud);
      if (!info.ok()) return ServiceFail("targets upload", info.status());
      args->json ? (void)std::printf("%s\n", TargetJson(*info).dump().c_str()) : PrintTarget(*info);
    } else if (get->parsed()) {
      auto info = (*client)->GetTarget(args->id);
      if (!info.ok()) return ServiceFail("targets get", info.status());
      args->json ? (void)std::printf("%s\n", TargetJson(*info).dump().c_str()) : PrintTarget(*info);
    } else if (list->parsed()) {
      auto all = (*client)->ListTargets();
      if (!all.ok()) return ServiceFail("targets list", all.status());
      if (args->json) {
        nlohmann::json targets = nlohmann::json::array();
        for (const TargetInfo& t : *all) targets.push_back(TargetJson(t));
        std::printf("%s\n", targets.dump().c_str());
      } else {
        for (const TargetInfo& t : *all) PrintTarget(t);
        std::printf("%zu targets\n", all->size());
      }
    } else if (remove->parsed()) {
      if (absl::Status s = (*client)->DeleteTarget(args->id); !s.ok()) {
        return ServiceFail("targets delete", s);
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
  auto json = std::make_shared<bool>(false);
  cmd->add_flag("--json", *json, "print one JSON object per server");
  return [connection, json]() -> int {
    auto client = connection->Connect();
    if (!client.ok()) return ServiceFail("health", client.status());
    const std::vector<std::string> replicas = (*client)->replicas();
    bool all_serving = true;
    for (std::size_t i = 0; i < replicas.size(); ++i) {
      auto health = (*client)->Health(i);
      if (!health.ok()) {
        ServiceFail("health", health.status());
        all_serving = false;
        continue;
      }
      if (*json) {
        std::printf("%s\n", nlohmann::json{{"server", replicas[i]},
                                           {"status", health->status},
                                           {"serving", health->serving}}
                                .dump()
                                .c_str());
      } else {
        if (replicas.size() > 1) std::printf("%s ", replicas[i].c_str());
        std::printf("%s\n", health->status.c_str());
      }
      all_serving = all_serving && health->serving;
    }
    return all_serving ? kExitOk : kExitFailed;
  };
}

CommandRunner AddStatsCommand(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand("stats", "print servers' counters and latencies (JSON)");
  auto connection = std::make_shared<ConnectionFlags>();
  connection->AddTo(*cmd, true);
  return [connection]() -> int {
    auto client = connection->Connect();
    if (!client.ok()) return ServiceFail("stats", client.status());
    const std::vector<std::string> replicas = (*client)->replicas();
    for (std::size_t i = 0; i < replicas.size(); ++i) {
      auto json = (*client)->StatsJson(i);
      if (!json.ok()) return ServiceFail("stats", json.status());
      if (replicas.size() > 1) std::printf("== %s\n", replicas[i].c_str());
      std::printf("%s\n", json->c_str());
    }
    return 0;
  };
}

}  // namespace mlsreg::cli
