// Soak benchmark for a running mlsreg server (scripts/soak.sh starts one): C good clients run
// upload / register / delete cycles on targets of their own while an attacker keeps streams open
// that announce data and send none, and uploads that declare huge clouds. Reports the server's
// RSS before, after a warm-up and at the end, errors by code for the good clients and the
// attacker, and the good clients' latency percentiles.
//
// usage: mlsreg_soak_bench --server ADDR --server-pid PID [--cycles 1000] [--clients 8]
//                          [--silent-streams 40] [--target-points 3000] [--source-points 6000]
#include <atomic>
#include <chrono>
#include <cstdio>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "bench_support.h"
#include "grpcpp/grpcpp.h"
#include "mlsreg/client/client.h"
#include "mlsreg/io/io.h"
#include "mlsreg/registration/registration.h"
#include "mlsreg/v1/mlsreg.grpc.pb.h"
#include "mlsreg/wire/convert.h"

namespace {

using Clock = std::chrono::steady_clock;
using mlsreg::bench::Arg;
using mlsreg::bench::Percentile;
using mlsreg::bench::RssMiB;

struct Tally {
  std::mutex mutex;
  std::map<std::string, int> codes;
  void Add(const std::string& code) {
    std::lock_guard<std::mutex> lock(mutex);
    ++codes[code];
  }
  std::string Text() {
    std::lock_guard<std::mutex> lock(mutex);
    std::string out;
    for (const auto& [code, n] : codes) out += code + "=" + std::to_string(n) + " ";
    return out.empty() ? "none" : out;
  }
};

mlsreg::PointCloud Head(const mlsreg::PointCloud& cloud, std::size_t n) {
  mlsreg::PointCloud out;
  out.points.assign(cloud.points.begin(), cloud.points.begin() + std::min(n, cloud.size()));
  return out;
}

// Keeps `count` silent streams open until `stop`: Register calls that announce a chunked source
// and send nothing, and CreateTarget calls that declare 20 M points. The server ends them (idle
// timeout, budgets); each is then opened again.
void Attack(const std::string& address, int count, const std::atomic<bool>& stop, Tally& tally) {
  auto channel = grpc::CreateChannel(address, grpc::InsecureChannelCredentials());
  auto registration = mlsreg::v1::RegistrationService::NewStub(channel);
  auto targets = mlsreg::v1::TargetService::NewStub(channel);
  mlsreg::v1::RegisterRequest register_header;
  register_header.mutable_header()->set_target_id("soak-attacker-target");
  mlsreg::v1::CloudHeader* source = register_header.mutable_header()->mutable_source();
  source->set_scalar_type(mlsreg::v1::SCALAR_TYPE_FLOAT64);
  source->set_point_count(100'000);
  mlsreg::v1::CreateTargetRequest upload_header;
  upload_header.mutable_header()->set_target_id("soak-huge");
  upload_header.mutable_header()->mutable_cloud()->set_scalar_type(mlsreg::v1::SCALAR_TYPE_FLOAT64);
  upload_header.mutable_header()->mutable_cloud()->set_point_count(20'000'000);

  struct Open {
    std::unique_ptr<grpc::ClientContext> context;
    std::unique_ptr<
        grpc::ClientReaderWriter<mlsreg::v1::RegisterRequest, mlsreg::v1::RegisterResponse>>
        stream;
    std::unique_ptr<grpc::ClientWriter<mlsreg::v1::CreateTargetRequest>> writer;
    mlsreg::v1::Target out;
    std::thread waiter;  // blocks in Finish until the server ends the call
    std::atomic<bool> done{false};
  };
  std::vector<std::unique_ptr<Open>> open;
  std::atomic<int> live{0};
  std::size_t opened = 0;
  while (!stop.load()) {
    // Reap the calls the server ended.
    std::erase_if(open, [](std::unique_ptr<Open>& o) {
      if (!o->done.load()) return false;
      o->waiter.join();
      return true;
    });
    // Reopen at most one stream per 10 ms: a steady attacker, not a connection flood.
    if (live.load() < count) {
      auto o = std::make_unique<Open>();
      o->context = std::make_unique<grpc::ClientContext>();
      o->context->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(120));
      const bool upload = opened++ % 4 == 3;
      if (upload) {
        o->writer = targets->CreateTarget(o->context.get(), &o->out);
        o->writer->Write(upload_header);
      } else {
        o->stream = registration->Register(o->context.get());
        o->stream->Write(register_header);
      }
      live.fetch_add(1);
      Open* raw = o.get();
      o->waiter = std::thread([raw, &live, &tally] {
        const grpc::Status status = raw->writer ? raw->writer->Finish() : raw->stream->Finish();
        tally.Add(absl::StatusCodeToString(static_cast<absl::StatusCode>(status.error_code())));
        live.fetch_sub(1);
        raw->done.store(true);
      });
      open.push_back(std::move(o));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  for (auto& o : open) o->context->TryCancel();
  for (auto& o : open) o->waiter.join();
}

}  // namespace

int main(int argc, char** argv) {
  const std::string address = Arg(argc, argv, "--server", "127.0.0.1:50051");
  const std::string pid = Arg(argc, argv, "--server-pid", "");
  const int cycles = std::stoi(Arg(argc, argv, "--cycles", "1000"));
  const int clients = std::stoi(Arg(argc, argv, "--clients", "8"));
  const int silent = std::stoi(Arg(argc, argv, "--silent-streams", "40"));
  auto target_scan =
      mlsreg::ReadPointCloud(Arg(argc, argv, "--target-file", "data/bunny/bun045.ply"));
  auto source_scan =
      mlsreg::ReadPointCloud(Arg(argc, argv, "--source-file", "data/bunny/bun000.ply"));
  if (!target_scan.ok() || !source_scan.ok()) {
    std::fprintf(stderr, "cannot read the clouds\n");
    return 2;
  }
  const mlsreg::PointCloud target =
      Head(*target_scan, std::stoul(Arg(argc, argv, "--target-points", "3000")));
  const mlsreg::PointCloud source =
      Head(*source_scan, std::stoul(Arg(argc, argv, "--source-points", "6000")));
  mlsreg::RegistrationOptions options;
  options.num_samples = 300;
  options.max_iterations = 15;

  mlsreg::client::ClientOptions client_options;
  client_options.address = address;
  client_options.deadline_seconds = 60;
  auto client = mlsreg::client::Client::Connect(client_options);
  if (!client.ok()) return 2;
  // The attacker's registrations need a target to pass validation up to their data.
  if (auto up = (*client)->UploadTarget("soak-attacker-target", target); !up.ok()) {
    std::fprintf(stderr, "upload failed: %s\n", std::string(up.status().message()).c_str());
    return 2;
  }

  const double rss_start = RssMiB(pid);
  std::atomic<bool> stop{false};
  Tally attacker, good;
  std::thread attack([&] { Attack(address, silent, stop, attacker); });

  std::atomic<int> next{0};
  std::mutex mutex;
  std::vector<double> cycle_seconds;
  double rss_warm = -1.0;
  const auto start = Clock::now();
  std::vector<std::thread> threads;
  for (int c = 0; c < clients; ++c) {
    threads.emplace_back([&, c] {
      for (int k = next.fetch_add(1); k < cycles; k = next.fetch_add(1)) {
        if (k == cycles / 10 && rss_warm < 0) {
          std::lock_guard<std::mutex> lock(mutex);
          rss_warm = RssMiB(pid);
        }
        const std::string id = "soak-" + std::to_string(c) + "-" + std::to_string(k);
        const auto t0 = Clock::now();
        absl::Status status = (*client)->UploadTarget(id, target).status();
        if (status.ok()) {
          status = (*client)->Register(id, source, mlsreg::Matrix4::Identity(), options).status();
        }
        if (absl::Status s = (*client)->DeleteTarget(id); status.ok()) status = s;
        const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
        good.Add(absl::StatusCodeToString(status.code()));
        std::lock_guard<std::mutex> lock(mutex);
        cycle_seconds.push_back(seconds);
      }
    });
  }
  for (std::thread& t : threads) t.join();
  const double wall = std::chrono::duration<double>(Clock::now() - start).count();
  stop.store(true);
  attack.join();
  const double rss_end = RssMiB(pid);

  std::printf(
      "soak: %d cycles (upload %zu points, register %zu points, delete) by %d clients, "
      "%d silent attacker streams, %.1f s\n",
      cycles, target.size(), source.size(), clients, silent, wall);
  std::printf("good clients: %s\n", good.Text().c_str());
  std::printf("attacker:     %s\n", attacker.Text().c_str());
  std::printf("cycle latency: p50 %.1f ms  p99 %.1f ms  max %.1f ms\n",
              Percentile(cycle_seconds, 0.5) * 1e3, Percentile(cycle_seconds, 0.99) * 1e3,
              Percentile(cycle_seconds, 1.0) * 1e3);
  std::printf(
      "server RSS: %.0f MiB at start, %.0f MiB after %d cycles, %.0f MiB at the end "
      "(growth after warm-up %+.1f MiB)\n",
      rss_start, rss_warm, cycles / 10, rss_end, rss_end - rss_warm);
  return 0;
}
