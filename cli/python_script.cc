#include "cli/python_script.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "absl/strings/str_cat.h"
#include "cli/temporary_directory.h"

extern char** environ;

namespace mlsreg::cli {
namespace {

absl::Status WriteFile(const std::filesystem::path& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) return absl::UnavailableError(absl::StrCat("cannot write ", path.string()));
  return absl::OkStatus();
}

// The last non-blank line of a text file, or "" when there is none.
std::string LastLine(const std::string& path) {
  std::ifstream in(path);
  std::string line, last;
  while (std::getline(in, line)) {
    if (line.find_first_not_of(" \t\r") != std::string::npos) last = line;
  }
  return last;
}

}  // namespace

absl::Status RunPythonScript(std::string_view what, std::string_view script, std::string_view input,
                             const std::vector<std::string>& args, const PythonNeeds& needs) {
  absl::StatusOr<TemporaryDirectory> temporary = TemporaryDirectory::Create("mlsreg-script", what);
  if (!temporary.ok()) return temporary.status();
  const std::filesystem::path& dir = temporary->path();
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
  // The script's stderr goes to a file: a traceback is for us, one line is for the user.
  const std::string errors = (dir / "stderr.txt").string();
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, errors.c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0600);
  pid_t pid = 0;
  const int spawned = posix_spawnp(&pid, python.c_str(), &actions, nullptr, raw.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) {
    return absl::FailedPreconditionError(
        absl::StrCat(std::string(what), ": cannot run ", python, "; it needs python3 with ",
                     std::string(needs.module), " (apt-get install ", std::string(needs.package),
                     ", or set MLSREG_PYTHON to a python3 that has it)"));
  }
  int status = 0;
  const bool waited = waitpid(pid, &status, 0) == pid;
  if (waited && WIFEXITED(status) && WEXITSTATUS(status) == 0) return absl::OkStatus();
  const std::string reason = LastLine(errors);
  const int code = waited && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  if (code == 3) {
    return absl::FailedPreconditionError(
        absl::StrCat(std::string(what), ": needs ", std::string(needs.module), ": ", reason,
                     " (apt-get install ", std::string(needs.package),
                     ", or set MLSREG_PYTHON to a python3 that has it)"));
  }
  if (code == 4) return absl::UnavailableError(absl::StrCat(std::string(what), ": ", reason));
  return absl::UnavailableError(
      absl::StrCat(std::string(what), ": the script failed", reason.empty() ? "" : ": ", reason));
}

}  // namespace mlsreg::cli
