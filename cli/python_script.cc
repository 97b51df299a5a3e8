#include "cli/python_script.h"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "absl/strings/str_cat.h"

extern char** environ;

namespace mlsreg::cli {
namespace {

absl::Status WriteFile(const std::filesystem::path& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) return absl::UnavailableError(absl::StrCat("cannot write ", path.string()));
  return absl::OkStatus();
}

}  // namespace

absl::Status RunPythonScript(std::string_view what, std::string_view script, std::string_view input,
                             const std::vector<std::string>& args) {
  std::string pattern = (std::filesystem::temp_directory_path() / "mlsreg-script-XXXXXX").string();
  if (mkdtemp(pattern.data()) == nullptr) {
    return absl::UnavailableError(
        absl::StrCat(std::string(what), ": cannot create a temporary directory"));
  }
  const std::filesystem::path dir(pattern);
  struct Cleanup {
    std::filesystem::path dir;
    ~Cleanup() {
      std::error_code ignored;
      std::filesystem::remove_all(dir, ignored);
    }
  } cleanup{dir};
  if (absl::Status s = WriteFile(dir / "script.py", script); !s.ok()) return s;
  if (absl::Status s = WriteFile(dir / "input.json", input); !s.ok()) return s;

  // MLSREG_PYTHON, else Debian's interpreter (which has python3-matplotlib), else PATH's.
  const char* chosen = std::getenv("MLSREG_PYTHON");
  std::string python = chosen != nullptr && *chosen                  ? chosen
                       : std::filesystem::exists("/usr/bin/python3") ? "/usr/bin/python3"
                                                                     : "python3";
  std::vector<std::string> argv = {python, (dir / "script.py").string(),
                                   (dir / "input.json").string()};
  argv.insert(argv.end(), args.begin(), args.end());
  std::vector<char*> raw;
  for (std::string& a : argv) raw.push_back(a.data());
  raw.push_back(nullptr);
  pid_t pid = 0;
  if (posix_spawnp(&pid, python.c_str(), nullptr, nullptr, raw.data(), environ) != 0) {
    return absl::FailedPreconditionError(absl::StrCat(
        std::string(what), ": needs python3 with matplotlib (apt-get install python3-matplotlib)"));
  }
  int status = 0;
  if (waitpid(pid, &status, 0) != pid || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    return absl::FailedPreconditionError(
        absl::StrCat(std::string(what),
                     ": the plotting script failed (see above; it needs python3-matplotlib)"));
  }
  return absl::OkStatus();
}

}  // namespace mlsreg::cli
