#include "cli/transport.h"

#include <dlfcn.h>

#include <cstdlib>
#include <filesystem>
#include <vector>

namespace mlsreg::cli {
namespace {

std::vector<std::string> Candidates() {
  if (const char* path = std::getenv("MLSREG_TRANSPORT"); path && *path) return {path};
  std::error_code error;
  const std::filesystem::path program = std::filesystem::read_symlink("/proc/self/exe", error);
  if (error) return {kTransportFile};  // the loader's own search path
  const std::filesystem::path dir = program.parent_path();
  return {(dir / kTransportFile).string(),
          (dir.parent_path() / "lib" / "mlsreg" / kTransportFile).string()};
}

absl::StatusOr<const TransportApi*> Load() {
  std::string reasons;
  for (const std::string& path : Candidates()) {
    void* module = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (module == nullptr) {
      reasons += "\n  " + std::string(dlerror());
      continue;
    }
    using Entry = const TransportApi* (*)();
    const auto entry = reinterpret_cast<Entry>(dlsym(module, kTransportEntry));
    if (entry == nullptr) {
      reasons += "\n  " + path + ": no " + kTransportEntry;
      continue;
    }
    const TransportApi* api = entry();
    if (api == nullptr || api->version != kTransportApiVersion) {
      reasons += "\n  " + path + ": another version of mlsreg's transport";
      continue;
    }
    return api;  // never unloaded: clients and servers it made live until the process ends
  }
  return absl::FailedPreconditionError(
      "the networked commands need mlsreg's transport module " + std::string(kTransportFile) +
      " (beside the mlsreg program, or named by MLSREG_TRANSPORT); tried:" + reasons);
}

}  // namespace

absl::StatusOr<const TransportApi*> Transport() {
  static const absl::StatusOr<const TransportApi*> loaded = Load();
  return loaded;
}

}  // namespace mlsreg::cli
