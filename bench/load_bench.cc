// Load generator for a running mlsreg server: N concurrent clients register the same source
// against one cached target and report throughput, latency percentiles and errors by code.
// It also times the same registration in-process, so the served/in-process ratio (the cost of
// the service layer) comes from one run on one machine.
//
// usage: mlsreg_load_bench --server ADDR --target-file T --source-file S [--clients 1,2,8,32]
//                          [--requests-per-client 4] [--samples 2000] [--server-pid PID]
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/str_split.h"
#include "bench_support.h"
#include "mlsreg/client/client.h"
#include "mlsreg/io/io.h"
#include "mlsreg/registration/registration.h"

namespace {

using Clock = std::chrono::steady_clock;
using mlsreg::bench::Arg;
using mlsreg::bench::Percentile;
using mlsreg::bench::RssMiB;

}  // namespace

int main(int argc, char** argv) {
  const std::string address = Arg(argc, argv, "--server", "127.0.0.1:50051");
  const std::string target_file = Arg(argc, argv, "--target-file", "data/bunny/bun045.ply");
  const std::string source_file = Arg(argc, argv, "--source-file", "data/bunny/bun000.ply");
  const std::string pid = Arg(argc, argv, "--server-pid", "");
  const int per_client = std::stoi(Arg(argc, argv, "--requests-per-client", "4"));
  std::vector<int> client_counts;
  for (absl::string_view c : absl::StrSplit(Arg(argc, argv, "--clients", "1,2,8,32"), ',')) {
    client_counts.push_back(std::stoi(std::string(c)));
  }
  mlsreg::RegistrationOptions options;
  options.num_samples = std::stoi(Arg(argc, argv, "--samples", "2000"));
  options.method = mlsreg::Method::kMlsSicp;

  auto target_cloud = mlsreg::ReadPointCloud(target_file);
  auto source = mlsreg::ReadPointCloud(source_file);
  if (!target_cloud.ok() || !source.ok()) {
    std::fprintf(stderr, "cannot read the clouds\n");
    return 2;
  }
  // A fixed start: identity (the bundled bunny scans overlap enough to converge from it).
  const mlsreg::Matrix4 initial = mlsreg::Matrix4::Identity();

  // In-process baseline, same inputs (median of 3).
  auto target = mlsreg::Target::Build(*target_cloud);
  std::vector<double> local;
  for (int i = 0; i < 3; ++i) {
    const auto start = Clock::now();
    auto r = mlsreg::Register(**target, *source, initial, options);
    local.push_back(std::chrono::duration<double>(Clock::now() - start).count());
    if (!r.ok()) return 2;
  }
  const double local_median = Percentile(local, 0.5);

  mlsreg::client::ClientOptions client_options;
  client_options.address = address;
  client_options.max_attempts = 1;  // count RESOURCE_EXHAUSTED instead of retrying it away
  auto client = mlsreg::client::Client::Connect(client_options);
  if (!client.ok()) return 2;
  const std::string target_id = "load-bench-target";
  auto uploaded = (*client)->UploadTarget(target_id, *target_cloud);
  if (!uploaded.ok() && uploaded.status().code() != absl::StatusCode::kAlreadyExists) {
    std::fprintf(stderr, "upload failed: %s\n", std::string(uploaded.status().message()).c_str());
    return 2;
  }

  std::printf("in-process registration: %.1f ms (median of 3)\n", local_median * 1e3);
  std::printf("%8s %9s %12s %10s %10s %10s %10s  %s\n", "clients", "requests", "throughput",
              "p50 ms", "p99 ms", "ratio p50", "RSS MiB", "errors");
  for (int clients : client_counts) {
    const double rss_before = RssMiB(pid);
    std::vector<double> latencies;
    std::map<std::string, int> errors;
    std::mutex mutex;
    const auto start = Clock::now();
    std::vector<std::thread> threads;
    for (int c = 0; c < clients; ++c) {
      threads.emplace_back([&] {
        for (int k = 0; k < per_client; ++k) {
          const auto t0 = Clock::now();
          auto r = (*client)->Register(target_id, *source, initial, options);
          const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
          std::lock_guard<std::mutex> lock(mutex);
          if (r.ok()) {
            latencies.push_back(seconds);
          } else {
            ++errors[absl::StatusCodeToString(r.status().code())];
          }
        }
      });
    }
    for (std::thread& t : threads) t.join();
    const double wall = std::chrono::duration<double>(Clock::now() - start).count();
    std::string error_text;
    for (const auto& [code, n] : errors) error_text += code + "=" + std::to_string(n) + " ";
    std::printf("%8d %9d %10.2f/s %10.1f %10.1f %10.2f %5.0f->%-4.0f %s\n", clients,
                clients * per_client, static_cast<double>(latencies.size()) / wall,
                Percentile(latencies, 0.5) * 1e3, Percentile(latencies, 0.99) * 1e3,
                Percentile(latencies, 0.5) / local_median, rss_before, RssMiB(pid),
                error_text.empty() ? "none" : error_text.c_str());
    std::fflush(stdout);
  }
  return 0;
}
