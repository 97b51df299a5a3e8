// `mlsreg batch`: runs every job of a manifest against a server with bounded concurrency.
// Each distinct target file is uploaded once (id derived from its name and content digest); results
// go to a CSV or JSONL file (by extension) one row per job; --resume skips jobs already done there.
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <thread>

#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "cli/batch_report.h"
#include "cli/commands.h"
#include "cli/connection_flags.h"
#include "cli/exit_codes.h"
#include "cli/registration_flags.h"
#include "cli/report.h"
#include "cli/shard_flags.h"
#include "mlsreg/evaluation/shard.h"
#include "mlsreg/io/io.h"
#include "mlsreg/io/manifest.h"

namespace mlsreg::cli {
namespace {

struct BatchArgs {
  std::string manifest, results = "results.csv", report;
  int concurrency = 4;
  bool resume = false;
  ShardFlags shard;
  RegistrationFlags flags;
  ConnectionFlags connection;
};

// A readable id that names the target's content: "<stem>-<16 hex digits of its digest>". A
// file replaced by another scan gets a new id (and is uploaded), the same content the same id
// whatever its path (and the upload is skipped: the server already has it).
std::string TargetIdFor(const std::string& path, const std::string& digest) {
  std::string stem;
  for (char c : std::filesystem::path(path).stem().string()) {
    stem +=
        (std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-') ? c : '_';
  }
  if (stem.empty() || stem.front() == '.') stem = "t" + stem;
  const std::string hex = digest.substr(digest.find(':') + 1, 16);
  return absl::StrFormat("%s-%s", stem.substr(0, 100), hex);
}

bool IsJsonl(const std::string& path) {
  return std::filesystem::path(path).extension() == ".jsonl";
}

// One extent of the result's pose covariance (VerificationScore::pose_rotation_sigma_deg or
// pose_translation_sigma), empty when it has none.
std::string PoseSigma(const JobOutcome& o, double VerificationScore::*sigma) {
  if (!o.verification || !o.verification->pose_covariance) return "";
  return absl::StrFormat("%.6g", (*o.verification).*sigma);
}

std::string CsvRow(const JobOutcome& o) {
  std::vector<std::string> f = {
      o.id,
      o.error.empty() ? "ok" : o.error,
      o.target_id,
      o.pose_error ? absl::StrFormat("%.6g", o.pose_error->rmse_d) : "",
      o.pose_error ? (o.pose_error->success ? "1" : "0") : "",
      absl::StrFormat("%d", o.iterations),
      o.termination,
      o.error.empty() ? FormatTransform(o.transform) : "",
      absl::StrFormat("%.4f", o.seconds),
      absl::StrFormat("%d", o.attempts),
      o.request_id,
      o.verified ? (*o.verified ? "1" : "0") : "",
      o.verification ? std::string(VerdictName(o.verification->verdict)) : "",
      PoseSigma(o, &VerificationScore::pose_rotation_sigma_deg),
      PoseSigma(o, &VerificationScore::pose_translation_sigma)};
  for (std::string& s : f) s = CsvField(s);
  return absl::StrJoin(f, ",");
}

std::string JsonRow(const JobOutcome& o) {
  nlohmann::json j = {{"id", o.id},
                      {"status", o.error.empty() ? "ok" : o.error},
                      {"target_id", o.target_id},
                      {"iterations", o.iterations},
                      {"termination", o.termination},
                      {"seconds", o.seconds},
                      {"attempts", o.attempts},
                      {"request_id", o.request_id}};
  if (o.error.empty()) {
    std::vector<double> t;
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) t.push_back(o.transform(r, c));
    }
    j["transform"] = t;
  }
  if (o.verified) j["verified"] = *o.verified;
  if (const std::optional<VerificationScore>& v = o.verification) {
    j["verdict"] = std::string(VerdictName(v->verdict));
    if (v->pose_covariance) {
      j["pose_covariance"] = PoseCovarianceJson(v->pose_covariance);
      j["pose_rotation_sigma_deg"] = v->pose_rotation_sigma_deg;
      j["pose_translation_sigma"] = v->pose_translation_sigma;
    }
  }
  if (o.pose_error) {
    j["rmse_d"] = o.pose_error->rmse_d;
    j["success"] = o.pose_error->success;
  }
  return j.dump();
}

// Ids of jobs already completed successfully in an existing results file.
std::set<std::string> CompletedJobs(const std::string& path) {
  std::set<std::string> done;
  std::ifstream in(path);
  std::string line;
  bool header = !IsJsonl(path);
  while (std::getline(in, line)) {
    if (header) {
      header = false;
      continue;
    }
    if (IsJsonl(path)) {
      auto j = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
      if (j.is_object() && j.value("status", "") == "ok") done.insert(j.value("id", ""));
    } else {
      auto fields = SplitCsvLine(line);
      if (fields.ok() && fields->size() > 1 && (*fields)[1] == "ok") done.insert((*fields)[0]);
    }
  }
  return done;
}

int RunBatch(const BatchArgs& args) {
  auto options = args.flags.ToOptions();
  if (!options.ok()) {
    std::fprintf(stderr, "mlsreg batch: %s\n", std::string(options.status().message()).c_str());
    return 2;
  }
  auto manifest = ReadManifest(args.manifest);
  if (!manifest.ok()) {
    std::fprintf(stderr, "mlsreg batch: %s\n", std::string(manifest.status().message()).c_str());
    return 2;
  }
  auto client = args.connection.Connect();
  if (!client.ok()) {
    std::fprintf(stderr, "mlsreg batch: %s\n", std::string(client.status().message()).c_str());
    return 2;
  }
  const absl::StatusOr<std::optional<ShardSpec>> shard = args.shard.ToSpec();
  if (!shard.ok()) {
    std::fprintf(stderr, "mlsreg batch: %s\n", std::string(shard.status().message()).c_str());
    return 2;
  }
  std::vector<std::size_t> indices;  // the manifest's problems this process runs
  if (*shard) {
    indices = ShardProblems(*manifest, **shard);
    std::fprintf(stderr, "mlsreg batch: shard %d of %d: %zu of %zu jobs\n", (*shard)->index,
                 (*shard)->count, indices.size(), manifest->problems.size());
  } else {
    for (std::size_t i = 0; i < manifest->problems.size(); ++i) indices.push_back(i);
  }
  const std::set<std::string> already =
      args.resume ? CompletedJobs(args.results) : std::set<std::string>{};
  std::vector<const ManifestProblem*> jobs;
  for (std::size_t i : indices) {
    const ManifestProblem& p = manifest->problems[i];
    if (!already.count(p.id)) jobs.push_back(&p);
  }
  std::fprintf(stderr, "mlsreg batch: %zu jobs (%zu already done), concurrency %d\n", jobs.size(),
               already.size(), args.concurrency);

  // Upload each distinct target once, identified by its content; one the server already has
  // costs a header (CreateTarget is idempotent and the declared digest lets it answer at once).
  std::map<std::string, std::string> target_ids;  // path -> id
  std::map<std::string, std::string> upload_errors;
  for (const ManifestProblem* p : jobs) {
    if (target_ids.count(p->target_path)) continue;
    // Always "upload": the client then holds the cloud and can upload it again if the target's
    // replica loses it or dies and the target moves to another replica.
    auto cloud = ReadPointCloud(p->target_path);
    absl::Status status = cloud.status();
    std::string id = "(unreadable)";
    if (cloud.ok()) {
      auto shared = std::make_shared<const PointCloud>(*std::move(cloud));
      id = TargetIdFor(p->target_path, (*client)->DigestAsSent(*shared));
      auto uploaded = (*client)->UploadTarget(id, shared);
      status = uploaded.status();
    }
    target_ids[p->target_path] = id;
    if (!status.ok()) upload_errors[p->target_path] = std::string(status.message());
    std::fprintf(stderr, "target %s on %s: %s\n", id.c_str(), (*client)->ReplicaFor(id).c_str(),
                 status.ok() ? "ready" : std::string(status.message()).c_str());
  }

  const bool append = args.resume && std::filesystem::exists(args.results);
  std::ofstream out(args.results, append ? std::ios::app : std::ios::trunc);
  if (!out) {
    std::fprintf(stderr, "mlsreg batch: cannot write '%s'\n", args.results.c_str());
    return 2;
  }
  if (!append && !IsJsonl(args.results)) {
    out << "id,status,target_id,rmse_d,success,iterations,termination,transform,seconds,"
           "attempts,request_id,verified,verdict,pose_rotation_sigma_deg,pose_translation_sigma\n";
  }
  std::mutex mutex;
  std::vector<JobOutcome> outcomes;  // for --report
  const auto batch_start = std::chrono::steady_clock::now();
  std::atomic<std::size_t> next{0};
  std::size_t done = 0, failed = 0, not_verified = 0;
  ProgressPrinter progress;
  auto worker = [&] {
    for (std::size_t i = next++; i < jobs.size(); i = next++) {
      const ManifestProblem& p = *jobs[i];
      JobOutcome o;
      o.id = p.id;
      o.target_id = target_ids[p.target_path];
      const auto start = std::chrono::steady_clock::now();
      if (upload_errors.count(p.target_path)) {
        o.error = "target upload failed: " + upload_errors[p.target_path];
      } else if (auto source = ReadPointCloud(p.source_path); !source.ok()) {
        o.error = std::string(source.status().message());
      } else {
        auto r = (*client)->Register(o.target_id, *source, p.initial.value_or(Matrix4::Identity()),
                                     *options, p.ground_truth);
        if (!r.ok()) {
          o.error = absl::StrFormat("%s: %s", absl::StatusCodeToString(r.status().code()),
                                    std::string(r.status().message()));
        } else {
          o.transform = r->result.transform;
          o.iterations = r->result.iterations;
          o.termination = std::string(TerminationName(r->result.termination));
          o.pose_error = r->ground_truth_error;
          o.attempts = r->attempts;
          o.request_id = r->request_id;
          o.verification = r->result.verification;  // any method's verdict
          if (o.verification) {
            o.verified = o.verification->verified();
          } else if (r->result.auto_report) {
            o.verified = r->result.auto_report->verified;
          }
        }
      }
      o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      std::lock_guard<std::mutex> lock(mutex);
      out << (IsJsonl(args.results) ? JsonRow(o) : CsvRow(o)) << "\n";
      out.flush();
      if (!args.report.empty()) outcomes.push_back(o);
      ++done;
      failed += !o.error.empty();
      not_verified += o.error.empty() && o.verified && !*o.verified;
      progress.Update(done, jobs.size(),
                      o.error.empty() ? absl::StrFormat("%s ok (%d iterations)", o.id, o.iterations)
                                      : absl::StrFormat("%s FAILED: %s", o.id, o.error));
    }
  };
  std::vector<std::thread> threads;
  for (int t = 0; t < std::max(1, args.concurrency); ++t) threads.emplace_back(worker);
  for (std::thread& t : threads) t.join();
  std::fprintf(stderr,
               "mlsreg batch: %zu done (%zu of them not verified), %zu failed; results in %s\n",
               done - failed, not_verified, failed, args.results.c_str());
  if (!args.report.empty()) {
    const BatchReportInfo info{
        args.manifest, std::string(MethodName(options->method)), args.connection.options().address,
        args.concurrency,
        std::chrono::duration<double>(std::chrono::steady_clock::now() - batch_start).count()};
    if (absl::Status s = WriteBatchReport(args.report, info, outcomes); !s.ok()) {
      std::fprintf(stderr, "mlsreg batch: %s\n", std::string(s.message()).c_str());
      return 2;
    }
    std::fprintf(stderr, "mlsreg batch: report in %s\n", args.report.c_str());
  }
  if (failed > 0) return kExitFailed;
  return not_verified > 0 ? kExitNotVerified : kExitOk;
}

}  // namespace

CommandRunner AddBatchCommand(CLI::App& app) {
  auto args = std::make_shared<BatchArgs>();
  CLI::App* cmd = app.add_subcommand(
      "batch", "register every job of a manifest (id,source,target[,gt][,init]) on a server");
  cmd->add_option("--manifest", args->manifest, "jobs CSV; paths relative to it")->required();
  cmd->add_option("--results", args->results, "results file: .csv or .jsonl")
      ->capture_default_str();
  cmd->add_option("--concurrency", args->concurrency, "registrations in flight")
      ->capture_default_str();
  cmd->add_flag("--resume", args->resume, "skip jobs already done in the results file, append");
  args->shard.AddTo(*cmd, "jobs");
  cmd->add_option("--report", args->report,
                  "write a self-contained HTML report of this run's jobs: failures first, a "
                  "table, the alpha-recall curve (with ground truth), a latency histogram");
  args->flags.AddTo(*cmd);
  args->connection.AddTo(*cmd, /*server_required=*/true);
  return [args] { return RunBatch(*args); };
}

}  // namespace mlsreg::cli
