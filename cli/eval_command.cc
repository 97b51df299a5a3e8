#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "cli/cloud_files.h"
#include "cli/commands.h"
#include "cli/embedded_scripts.h"
#include "cli/exit_codes.h"
#include "cli/python_script.h"
#include "cli/registration_flags.h"
#include "cli/report.h"
#include "cli/shard_flags.h"
#include "cli/temporary_directory.h"
#include "mlsreg/core/parallel_for.h"
#include "mlsreg/evaluation/evaluation.h"
#include "mlsreg/evaluation/shard.h"

namespace mlsreg::cli {
namespace {

struct EvalArgs {
  std::vector<std::string> manifests;
  std::string methods = std::string(MethodName(RegistrationOptions().method));  // auto
  std::string out;
  std::string json;  // the summary as JSON
  std::string label;
  double angle_deg = 0.0;
  double translation_d = 0.0;
  std::uint64_t perturb_seed = 1;
  bool uniform_rotation = false;
  double translation_max_d = 0.0;
  int jobs = HardwareThreads();
  int threads = 1;
  ShardFlags shard;
  std::vector<std::string> merge;  // shard CSVs to merge instead of running
  std::string dask;                // a Dask scheduler's address: run the shards there
  int dask_shards = 0;             // 0: one per worker
  RegistrationFlags flags;
};

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// The 90th percentile, linearly interpolated between the order statistics (numpy's default).
double Percentile90(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double at = 0.9 * static_cast<double>(v.size() - 1);
  const std::size_t below = static_cast<std::size_t>(at);
  const double above = below + 1 < v.size() ? v[below + 1] : v[below];
  return v[below] + (at - static_cast<double>(below)) * (above - v[below]);
}

std::string JoinNumbers(const std::vector<double>& values,
                        const absl::FormatSpec<double>& format = "%.5g") {
  std::vector<std::string> parts;
  parts.reserve(values.size());
  for (double v : values) parts.push_back(absl::StrFormat(format, v));
  return absl::StrJoin(parts, " ");
}

std::string TraceColumn(const RegistrationResult& r, bool elapsed) {
  std::vector<double> values;
  for (const IterationReport& it : r.trace) {
    values.push_back(elapsed ? it.elapsed_seconds : it.rmse_d);
  }
  return JoinNumbers(values);
}

const char* kFixedColumns[] = {"manifest",
                               "id",
                               "method",
                               "source",
                               "target",
                               "status",
                               "rmse_d",
                               "success",
                               "rotation_error_deg",
                               "translation_error_d",
                               "initial_rmse_d",
                               "iterations",
                               "termination",
                               "converged",
                               "sampling_distance",
                               "time_total_s",
                               "time_preprocessing_s",
                               "time_subsampling_s",
                               "time_matching_s",
                               "time_optimisation_s",
                               "target_build_s",
                               "mls_radius_d",
                               "target_noise_d",
                               "source_noise_d",
                               "trace_rmse_d",
                               "trace_elapsed_s",
                               "trace_error_d",
                               "initial_rotation_error_deg",
                               "initial",
                               "verified",
                               "verdict",
                               "verify_overlap_fraction",
                               "verify_explained_fraction",
                               "verify_worst_direction_fraction",
                               "verify_band_d",
                               "verify_pose_rotation_sigma_deg",
                               "verify_pose_translation_sigma_d",
                               "verify_pose_covariance",
                               "auto_chosen",
                               "auto_candidates",
                               "auto_early_exit",
                               "auto_start_fraction",
                               "auto_fraction",
                               "auto_rmse_d",
                               "auto_inlier_distance_d",
                               "auto_finish",
                               "auto_finish_kept",
                               "auto_finish_moved_d",
                               "label"};

// `text` right-aligned in `width`, or "-" when there is no value (every run failed to run).
std::string Cell(const std::vector<double>& values, const std::string& text, int width) {
  return absl::StrFormat("%*s", width, values.empty() ? "-" : text);
}

bool Perturbs(const EvalArgs& args) {
  return args.angle_deg != 0.0 || args.translation_d != 0.0 || args.uniform_rotation ||
         args.translation_max_d != 0.0;
}

// The runs of an evaluation as CSV cells (unquoted), one row per (problem, method), in the order
// of the manifests, their problems and --methods. The summary is computed from these cells, so a
// run and a merge of its shards print the same numbers.
struct EvalTable {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;

  std::size_t Column(std::string_view name) const {
    return static_cast<std::size_t>(std::find(header.begin(), header.end(), name) - header.begin());
  }
};

std::vector<std::string> HeaderFor(const std::vector<Manifest>& manifests) {
  std::vector<std::string> header(std::begin(kFixedColumns), std::end(kFixedColumns));
  for (const Manifest& manifest : manifests) {
    for (const std::string& c : manifest.extra_columns) {
      if (std::find(header.begin() + std::size(kFixedColumns), header.end(), c) == header.end()) {
        header.push_back(c);
      }
    }
  }
  return header;
}

absl::StatusOr<std::vector<Manifest>> ReadManifests(const EvalArgs& args) {
  std::vector<Manifest> manifests;
  for (const std::string& path : args.manifests) {
    auto manifest = ReadManifest(path);
    if (!manifest.ok()) return manifest.status();
    manifests.push_back(*std::move(manifest));
  }
  return manifests;
}

absl::StatusOr<std::vector<Method>> ParseMethods(const std::string& list) {
  std::vector<Method> methods;
  for (absl::string_view name : absl::StrSplit(list, ',', absl::SkipEmpty())) {
    auto method = ParseMethod(std::string_view(name.data(), name.size()));
    if (!method.ok()) return method.status();
    methods.push_back(*method);
  }
  if (methods.empty()) return absl::InvalidArgumentError("--methods is empty");
  return methods;
}

// One outcome as the cells of kFixedColumns (the extra columns are appended by the caller).
std::vector<std::string> OutcomeCells(const std::string& path, const ManifestProblem& p,
                                      const ProblemOutcome& o, const std::string& label) {
  std::vector<std::string> f = {path, p.id, std::string(MethodName(o.method)), p.source_path,
                                p.target_path};
  if (!o.status.ok()) {
    f.push_back(std::string(o.status.message()));
    f.resize(std::size(kFixedColumns) - 1);
    f.push_back(label);
    return f;
  }
  const RegistrationResult& r = o.result;
  f.push_back("ok");
  f.push_back(absl::StrFormat("%.6g", o.error.rmse_d));
  f.push_back(o.error.success ? "1" : "0");
  f.push_back(absl::StrFormat("%.6g", o.error.rotation_deg));
  f.push_back(absl::StrFormat("%.6g", o.error.translation_d));
  f.push_back(absl::StrFormat("%.6g", o.initial_error.rmse_d));
  f.push_back(absl::StrFormat("%d", r.iterations));
  f.push_back(std::string(TerminationName(r.termination)));
  f.push_back(r.converged ? "1" : "0");
  f.push_back(absl::StrFormat("%.9g", r.sampling_distance));
  for (double t : {r.timings.total, r.timings.preprocessing, r.timings.subsampling,
                   r.timings.matching, r.timings.optimisation, o.target_build_seconds}) {
    f.push_back(absl::StrFormat("%.6g", t));
  }
  for (double v : {r.mls_radius_d, r.target_noise_d, r.source_noise_d}) {
    f.push_back(absl::StrFormat("%.4g", v));
  }
  f.push_back(TraceColumn(r, false));
  f.push_back(TraceColumn(r, true));
  f.push_back(JoinNumbers(o.trace_error_d));
  f.push_back(absl::StrFormat("%.6g", o.initial_error.rotation_deg));
  std::vector<double> initial;
  for (int i = 0; i < 16; ++i) initial.push_back(o.initial(i / 4, i % 4));
  f.push_back(JoinNumbers(initial, "%.10g"));
  if (const std::optional<VerificationScore>& v = r.verification) {
    f.push_back(v->verified() ? "1" : "0");
    f.push_back(std::string(VerdictName(v->verdict)));
    f.push_back(absl::StrFormat("%.4f", v->inlier_fraction));
    f.push_back(absl::StrFormat("%.4f", v->explained_fraction));
    f.push_back(absl::StrFormat("%.4f", v->worst_direction_fraction));
    f.push_back(absl::StrFormat("%.4f", v->inlier_distance_d));
    // The pose covariance (registration/verification.h): empty cells when some direction has too
    // little evidence for one.
    if (const auto& c = v->pose_covariance) {
      f.push_back(absl::StrFormat("%.6g", v->pose_rotation_sigma_deg));
      f.push_back(absl::StrFormat("%.6g", v->pose_translation_sigma / r.sampling_distance));
      std::vector<double> row_major;
      for (int i = 0; i < 36; ++i) row_major.push_back((*c)(i / 6, i % 6));
      f.push_back(JoinNumbers(row_major, "%.6g"));
    } else {
      f.insert(f.end(), 3, std::string());
    }
  } else {
    f.insert(f.end(), 9, std::string());
  }
  if (const std::optional<AutoReport>& a = r.auto_report; a && !a->candidates.empty()) {
    f.push_back(absl::StrFormat("%d", a->chosen));
    f.push_back(absl::StrFormat("%zu", a->candidates.size()));
    f.push_back(a->early_exit ? "1" : "0");
    f.push_back(absl::StrFormat("%.4f", a->candidates[0].score.inlier_fraction));
    f.push_back(absl::StrFormat("%.4f", a->verification.inlier_fraction));
    f.push_back(absl::StrFormat("%.4f", a->verification.rmse_d));
    f.push_back(absl::StrFormat("%.4f", a->verification.inlier_distance_d));
    f.push_back(std::string(FinishKindName(a->finish.kind)));
    f.push_back(a->finish.kept ? "1" : "0");
    f.push_back(absl::StrFormat("%.4f", a->finish.moved / r.sampling_distance));
  } else {
    f.insert(f.end(), 10, std::string());
  }
  f.push_back(label);
  return f;
}

// Runs the evaluation (this process's shard of it, when sharded) into a table.
absl::StatusOr<EvalTable> RunTable(const EvalArgs& args, const EvaluationOptions& base,
                                   const std::vector<Manifest>& manifests,
                                   const std::optional<ShardSpec>& shard) {
  EvalTable table;
  table.header = HeaderFor(manifests);
  ProgressPrinter progress;
  for (std::size_t m = 0; m < manifests.size(); ++m) {
    const Manifest& manifest = manifests[m];
    const std::string& path = args.manifests[m];
    const auto without_start =
        std::count_if(manifest.problems.begin(), manifest.problems.end(),
                      [](const ManifestProblem& p) { return !p.initial.has_value(); });
    if (without_start > 0 && !Perturbs(args)) {
      std::fprintf(stderr,
                   "mlsreg eval: warning: %s: %ld of %zu problems have no init column and no "
                   "--perturb-* flag is given, so they start at the ground truth: their errors "
                   "only show how far a method drifts from it (give --perturb-angle and "
                   "--perturb-translation to start elsewhere)\n",
                   path.c_str(), static_cast<long>(without_start), manifest.problems.size());
    }
    EvaluationOptions options = base;
    if (shard) {
      options.problems = ShardProblems(manifest, *shard);
      if (options.problems.empty()) continue;  // none of this manifest's targets is ours
    }
    auto outcomes = RunEvaluation(
        manifest, options, [&](const ProblemOutcome& o, std::size_t done, std::size_t total) {
          const ManifestProblem& p = manifest.problems[o.problem_index];
          progress.Update(
              done, total,
              o.status.ok()
                  ? absl::StrFormat("%s %s: %.3f d", p.id, MethodName(o.method), o.error.rmse_d)
                  : absl::StrFormat("%s %s: ERROR %s", p.id, MethodName(o.method),
                                    std::string(o.status.message())));
        });
    if (!outcomes.ok()) return outcomes.status();
    for (const ProblemOutcome& o : *outcomes) {
      const ManifestProblem& p = manifest.problems[o.problem_index];
      std::vector<std::string> row = OutcomeCells(path, p, o, args.label);
      for (std::size_t c = std::size(kFixedColumns); c < table.header.size(); ++c) {
        std::string value;
        for (const auto& [name, v] : p.extra) {
          if (name == table.header[c]) value = v;
        }
        row.push_back(value);
      }
      table.rows.push_back(std::move(row));
    }
  }
  return table;
}

// Reads shard CSVs written by `eval --shard` with the same --pairs and --methods into the table
// one run would have written: rows in manifest, problem and method order. FAILED_PRECONDITION
// when a run is missing (a shard file is missing or incomplete) or appears twice.
absl::StatusOr<EvalTable> MergeTable(const EvalArgs& args, const std::vector<Method>& methods,
                                     const std::vector<Manifest>& manifests) {
  EvalTable table;
  table.header = HeaderFor(manifests);
  // Slot (manifest m, problem i, method k) at (offset[m] + i) * methods + k.
  std::vector<std::size_t> offset;
  std::size_t problems = 0;
  for (const Manifest& manifest : manifests) {
    offset.push_back(problems);
    problems += manifest.problems.size();
  }
  std::vector<std::vector<std::string>> slots(problems * methods.size());
  std::vector<std::uint8_t> filled(slots.size(), 0);
  for (const std::string& file : args.merge) {
    std::ifstream in(file);
    if (!in) return absl::NotFoundError("--merge: cannot read '" + file + "'");
    std::string line;
    std::vector<std::string> columns;
    int line_number = 0;
    while (std::getline(in, line)) {
      ++line_number;
      if (line.empty()) continue;
      auto fields = SplitCsvLine(line);
      if (!fields.ok()) {
        return absl::InvalidArgumentError(absl::StrFormat("--merge: %s line %d: %s", file,
                                                          line_number, fields.status().message()));
      }
      if (columns.empty()) {
        columns = *std::move(fields);
        for (const char* required : {"manifest", "id", "method"}) {
          if (std::find(columns.begin(), columns.end(), required) == columns.end()) {
            return absl::InvalidArgumentError(absl::StrFormat(
                "--merge: %s is not an eval results CSV (no column '%s')", file, required));
          }
        }
        continue;
      }
      auto cell = [&](std::string_view name) -> std::string {
        const auto at = std::find(columns.begin(), columns.end(), name) - columns.begin();
        return static_cast<std::size_t>(at) < fields->size() ? (*fields)[at] : std::string();
      };
      const std::string manifest_path = cell("manifest"), id = cell("id");
      const auto m = std::find(args.manifests.begin(), args.manifests.end(), manifest_path) -
                     args.manifests.begin();
      auto method = ParseMethod(cell("method"));
      const auto k = method.ok()
                         ? std::find(methods.begin(), methods.end(), *method) - methods.begin()
                         : static_cast<std::ptrdiff_t>(methods.size());
      if (static_cast<std::size_t>(m) == args.manifests.size() ||
          static_cast<std::size_t>(k) == methods.size()) {
        return absl::InvalidArgumentError(absl::StrFormat(
            "--merge: %s line %d: manifest '%s' and method '%s' must be among --pairs and "
            "--methods (merge with the flags the shards ran with)",
            file, line_number, manifest_path, cell("method")));
      }
      // The first problem with this id whose slot is free (ids may repeat).
      const std::vector<ManifestProblem>& list = manifests[m].problems;
      std::size_t slot = slots.size();
      bool duplicate = false;
      for (std::size_t i = 0; i < list.size(); ++i) {
        if (list[i].id != id) continue;
        const std::size_t at = (offset[m] + i) * methods.size() + static_cast<std::size_t>(k);
        if (!filled[at]) {
          slot = at;
          break;
        }
        duplicate = true;
      }
      if (slot == slots.size()) {
        return absl::FailedPreconditionError(absl::StrFormat(
            "--merge: %s line %d: %s %s of %s %s", file, line_number, id, cell("method"),
            manifest_path,
            duplicate ? "appears twice (the same shard given twice?)" : "is not in the manifest"));
      }
      std::vector<std::string> row;
      for (const std::string& name : table.header) row.push_back(cell(name));
      slots[slot] = std::move(row);
      filled[slot] = 1;
    }
  }
  std::vector<std::string> missing;
  for (std::size_t m = 0; m < manifests.size(); ++m) {
    for (std::size_t i = 0; i < manifests[m].problems.size(); ++i) {
      for (std::size_t k = 0; k < methods.size(); ++k) {
        if (!filled[(offset[m] + i) * methods.size() + k]) {
          missing.push_back(
              absl::StrCat(manifests[m].problems[i].id, " ", std::string(MethodName(methods[k]))));
        }
      }
    }
  }
  if (!missing.empty()) {
    const std::size_t shown = std::min<std::size_t>(missing.size(), 5);
    return absl::FailedPreconditionError(absl::StrFormat(
        "--merge: %zu of %zu runs are missing (%s%s): a shard's file is missing or incomplete",
        missing.size(), slots.size(),
        absl::StrJoin(missing.begin(), missing.begin() + static_cast<std::ptrdiff_t>(shown), ", "),
        missing.size() > shown ? ", ..." : ""));
  }
  table.rows = std::move(slots);
  return table;
}

// Writes the CSV, the failures, the summary and the JSON summary of `table`; the exit code.
int Report(const EvalArgs& args, const std::vector<Method>& methods, const EvalTable& table) {
  std::string csv = absl::StrJoin(table.header, ",") + "\n";
  for (const std::vector<std::string>& row : table.rows) {
    std::vector<std::string> quoted;
    for (const std::string& s : row) quoted.push_back(CsvField(s));
    csv += absl::StrJoin(quoted, ",") + "\n";
  }
  if (args.out.empty() || args.out == "-") {
    std::fputs(csv.c_str(), stdout);
  } else {
    std::ofstream out(args.out);
    out << csv;
    if (!out) return ExitFor("eval", absl::UnavailableError("cannot write '" + args.out + "'"));
  }

  const std::size_t manifest = table.Column("manifest"), id = table.Column("id"),
                    method = table.Column("method"), status = table.Column("status"),
                    rmse = table.Column("rmse_d"), success = table.Column("success"),
                    time = table.Column("time_total_s");
  std::map<std::string, std::vector<double>> rmse_by_method, time_by_method;
  std::map<std::string, int> successes, runs, errors;
  std::vector<std::string> failures;  // one line per run that could not run
  for (const std::vector<std::string>& row : table.rows) {
    const std::string& m = row[method];
    ++runs[m];
    if (row[status] != "ok") {
      ++errors[m];
      failures.push_back(
          absl::StrFormat("mlsreg eval: %s (%s, %s): %s", row[id], m, row[manifest], row[status]));
      continue;
    }
    double value = 0.0;
    rmse_by_method[m].push_back(absl::SimpleAtod(row[rmse], &value) ? value : 0.0);
    time_by_method[m].push_back(absl::SimpleAtod(row[time], &value) ? value : 0.0);
    successes[m] += row[success] == "1";
  }

  for (const std::string& line : failures) std::fprintf(stderr, "%s\n", line.c_str());
  std::FILE* summary = args.out.empty() || args.out == "-" ? stderr : stdout;
  std::fprintf(summary, "%-18s %5s %9s %7s %14s %14s %14s %12s\n", "method", "runs", "success",
               "errors", "median RMSE/d", "mean RMSE/d", "90th pct", "median time");
  for (Method method_id : methods) {
    const std::string m(MethodName(method_id));
    const std::vector<double>& e = rmse_by_method[m];
    double mean = 0.0;
    for (double v : e) mean += v;
    if (!e.empty()) mean /= static_cast<double>(e.size());
    std::fprintf(summary, "%-18s %5d %4d/%-4d %7d %s %s %s %s\n", m.c_str(), runs[m], successes[m],
                 runs[m], errors[m], Cell(e, absl::StrFormat("%.4f", Median(e)), 14).c_str(),
                 Cell(e, absl::StrFormat("%.4f", mean), 14).c_str(),
                 Cell(e, absl::StrFormat("%.4f", Percentile90(e)), 14).c_str(),
                 Cell(e, absl::StrFormat("%.3f s", Median(time_by_method[m])), 12).c_str());
  }
  if (!failures.empty()) {
    std::fprintf(summary,
                 "(%zu runs could not run, see above: the RMSE and time columns are over the "
                 "runs that did)\n",
                 failures.size());
  }
  if (!args.json.empty()) {
    nlohmann::json list = nlohmann::json::array();
    for (Method method_id : methods) {
      const std::string m(MethodName(method_id));
      const bool ran = !rmse_by_method[m].empty();
      list.push_back(
          {{"method", m},
           {"runs", runs[m]},
           {"successes", successes[m]},
           {"errors", errors[m]},
           {"median_rmse_d", ran ? nlohmann::json(Median(rmse_by_method[m])) : nullptr},
           {"p90_rmse_d", ran ? nlohmann::json(Percentile90(rmse_by_method[m])) : nullptr},
           {"median_time_s", ran ? nlohmann::json(Median(time_by_method[m])) : nullptr}});
    }
    std::ofstream out(args.json);
    out << nlohmann::json{{"methods", list}}.dump(2) << "\n";
    if (!out)
      return ExitFor("eval",
                     absl::UnavailableError("cannot write --json file '" + args.json + "'"));
  }
  for (Method method_id : methods) {
    const std::string m(MethodName(method_id));
    if (successes[m] != runs[m]) return kExitMissed;
  }
  return kExitOk;
}

// This process's `eval` flags as typed, without those that choose where the runs go and where
// the results are written (--dask, --dask-shards, --out, --json): what each shard on a Dask
// worker runs with.
absl::StatusOr<std::vector<std::string>> FlagsForEachShard() {
  std::ifstream in("/proc/self/cmdline", std::ios::binary);
  std::vector<std::string> argv;
  for (std::string arg; std::getline(in, arg, '\0');) argv.push_back(arg);
  const auto eval = std::find(argv.begin(), argv.end(), "eval");
  if (eval == argv.end()) return absl::InternalError("--dask: cannot read this command's flags");
  std::vector<std::string> flags;
  for (auto it = eval + 1; it != argv.end(); ++it) {
    bool dropped = false;
    for (const char* flag : {"--dask", "--dask-shards", "--out", "--json"}) {
      if (*it == flag) {
        ++it;  // and its value
        dropped = true;
        break;
      }
      if (it->rfind(std::string(flag) + "=", 0) == 0) {
        dropped = true;
        break;
      }
    }
    if (it == argv.end()) break;
    if (!dropped) flags.push_back(*it);
  }
  return flags;
}

// Runs the evaluation's shards on the Dask cluster at args.dask (cli/eval_dask.py) and merges
// them into the table one local run writes.
absl::StatusOr<EvalTable> RunOnDask(const EvalArgs& args, const std::vector<Method>& methods,
                                    const std::vector<Manifest>& manifests) {
  auto flags = FlagsForEachShard();
  if (!flags.ok()) return flags.status();
  std::error_code error;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", error);
  if (error) return absl::InternalError("--dask: cannot find this program's path");
  absl::StatusOr<TemporaryDirectory> temporary =
      TemporaryDirectory::Create("mlsreg-shards", "--dask");
  if (!temporary.ok()) return temporary.status();
  const std::filesystem::path& dir = temporary->path();
  const nlohmann::json job = {{"scheduler", args.dask},
                              {"mlsreg", exe.string()},
                              {"args", *flags},
                              {"cwd", std::filesystem::current_path().string()},
                              {"shards", args.dask_shards}};
  if (absl::Status s = RunPythonScript("--dask", kEvalDaskScript, job.dump(), {dir.string()},
                                       {"distributed", "python3-distributed"});
      !s.ok()) {
    return s;
  }
  EvalArgs merge = args;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (entry.path().extension() == ".csv") merge.merge.push_back(entry.path().string());
  }
  std::sort(merge.merge.begin(), merge.merge.end());
  return MergeTable(merge, methods, manifests);
}

int RunEval(const EvalArgs& args) {
  auto registration = args.flags.ToOptions();
  if (!registration.ok()) return ExitFor("eval", registration.status());
  for (const auto& [flag, path] :
       {std::pair{"--out", &args.out}, std::pair{"--json", &args.json}}) {
    if (path->empty() || *path == "-") continue;
    if (absl::Status s = CheckWritable(flag, *path); !s.ok()) return ExitFor("eval", s);
  }
  auto methods = ParseMethods(args.methods);
  if (!methods.ok()) return ExitFor("eval", methods.status());
  const bool sharded = args.shard.given();
  if (!args.merge.empty() && sharded) {
    return ExitFor("eval",
                   absl::InvalidArgumentError("--merge combines shards: give it without --shard"));
  }
  if (!args.dask.empty() && (sharded || !args.merge.empty())) {
    return ExitFor("eval",
                   absl::InvalidArgumentError(
                       "--dask runs every shard itself: give it without --shard or --merge"));
  }
  const absl::StatusOr<std::optional<ShardSpec>> shard = args.shard.ToSpec();
  if (!shard.ok()) return ExitFor("eval", shard.status());
  auto manifests = ReadManifests(args);
  if (!manifests.ok()) return ExitFor("eval", manifests.status());

  absl::StatusOr<EvalTable> table;
  if (!args.merge.empty()) {
    table = MergeTable(args, *methods, *manifests);
  } else if (!args.dask.empty()) {
    table = RunOnDask(args, *methods, *manifests);
  } else {
    EvaluationOptions options;
    options.registration = *registration;
    options.perturbation = {args.angle_deg, args.translation_d, args.perturb_seed,
                            args.uniform_rotation, args.translation_max_d};
    options.jobs = args.jobs;
    options.threads = args.threads;
    options.methods = *methods;
    table = RunTable(args, options, *manifests, *shard);
  }
  if (!table.ok()) return ExitFor("eval", table.status());
  return Report(args, *methods, *table);
}

}  // namespace

CommandRunner AddEvalCommand(CLI::App& app) {
  auto args = std::make_shared<EvalArgs>();
  CLI::App* cmd = app.add_subcommand(
      "eval", "run methods over manifests with ground truth (id,source,target,gt[,init])");
  cmd->add_option("--pairs", args->manifests, "manifest CSV (repeatable)")->required();
  cmd->add_option("--methods", args->methods,
                  "comma-separated methods (default: the default method, auto)")
      ->capture_default_str();
  cmd->add_option("--out", args->out, "results CSV (default: stdout)");
  cmd->add_option("--json", args->json, "write the summary per method as JSON to this file");
  cmd->add_option("--label", args->label, "written in every row's label column (e.g. a variant)");
  cmd->add_option("--perturb-angle", args->angle_deg,
                  "rotate each start pose by this angle (degrees) about a seeded random axis")
      ->capture_default_str();
  cmd->add_option("--perturb-translation", args->translation_d,
                  "and translate it by this many d in a seeded random direction")
      ->capture_default_str();
  cmd->add_option("--perturb-seed", args->perturb_seed, "perturbation seed")->capture_default_str();
  cmd->add_flag("--perturb-uniform-rotation", args->uniform_rotation,
                "rotate each start uniformly on SO(3) (any angle) instead of by --perturb-angle");
  cmd->add_option("--perturb-translation-max", args->translation_max_d,
                  "draw each translation's length uniformly between --perturb-translation and "
                  "this (units of d)");
  cmd->add_option("--jobs", args->jobs, "registrations run in parallel (default: all cores)");
  cmd->add_option("--threads", args->threads,
                  "threads inside each registration (jobs x threads <= cores; results do not "
                  "depend on it)")
      ->capture_default_str()
      ->check(CLI::Range(1, 256));
  args->shard.AddTo(*cmd, "problems (merge the shards' --out files with --merge)");
  cmd->add_option("--merge", args->merge,
                  "instead of running, merge these shard CSVs (from --shard runs with the same "
                  "--pairs and --methods) into the CSV, summary and --json one run writes")
      ->expected(1, -1);
  cmd->add_option("--dask", args->dask,
                  "run the evaluation on the Dask cluster of this scheduler (tcp://HOST:PORT): "
                  "one `eval --shard` task per shard, merged into what one run writes; the "
                  "workers need this mlsreg and the manifests' files at the same paths");
  cmd->add_option("--dask-shards", args->dask_shards, "shards for --dask (default: one per worker)")
      ->check(CLI::Range(1, kMaxShards));
  args->flags.AddTo(*cmd, /*method_flag=*/false);
  return [args] { return RunEval(*args); };
}

}  // namespace mlsreg::cli
