#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "cli/cloud_files.h"
#include "cli/commands.h"
#include "cli/exit_codes.h"
#include "cli/registration_flags.h"
#include "cli/report.h"
#include "mlsreg/core/parallel_for.h"
#include "mlsreg/evaluation/evaluation.h"

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
  RegistrationFlags flags;
};

int Fail(const absl::Status& status) {
  std::fprintf(stderr, "mlsreg eval: %s\n", std::string(status.message()).c_str());
  return status.code() == absl::StatusCode::kInvalidArgument ? kExitBadInput : kExitFailed;
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
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
                               "auto_chosen",
                               "auto_candidates",
                               "auto_early_exit",
                               "auto_start_fraction",
                               "auto_fraction",
                               "auto_rmse_d",
                               "auto_inlier_distance_d",
                               "label"};

// `text` right-aligned in `width`, or "-" when there is no value (every run failed to run).
std::string Cell(const std::vector<double>& values, const std::string& text, int width) {
  return absl::StrFormat("%*s", width, values.empty() ? "-" : text);
}

bool Perturbs(const EvalArgs& args) {
  return args.angle_deg != 0.0 || args.translation_d != 0.0 || args.uniform_rotation ||
         args.translation_max_d != 0.0;
}

int RunEval(const EvalArgs& args) {
  auto registration = args.flags.ToOptions();
  if (!registration.ok()) return Fail(registration.status());
  for (const auto& [flag, path] :
       {std::pair{"--out", &args.out}, std::pair{"--json", &args.json}}) {
    if (path->empty() || *path == "-") continue;
    if (absl::Status s = CheckWritable(flag, *path); !s.ok()) return Fail(s);
  }
  EvaluationOptions options;
  options.registration = *registration;
  options.perturbation = {args.angle_deg, args.translation_d, args.perturb_seed,
                          args.uniform_rotation, args.translation_max_d};
  options.jobs = args.jobs;
  options.threads = args.threads;
  options.methods.clear();
  for (absl::string_view name : absl::StrSplit(args.methods, ',', absl::SkipEmpty())) {
    auto method = ParseMethod(std::string_view(name.data(), name.size()));
    if (!method.ok()) return Fail(method.status());
    options.methods.push_back(*method);
  }
  if (options.methods.empty()) return Fail(absl::InvalidArgumentError("--methods is empty"));

  std::vector<std::string> extra_columns;
  std::vector<std::string> rows;
  std::map<Method, std::vector<double>> rmse_by_method, time_by_method;
  std::map<Method, int> successes, runs, errors;
  std::vector<std::string> failures;  // one line per run that could not run
  ProgressPrinter progress;
  for (const std::string& path : args.manifests) {
    auto manifest = ReadManifest(path);
    if (!manifest.ok()) return Fail(manifest.status());
    const auto without_start =
        std::count_if(manifest->problems.begin(), manifest->problems.end(),
                      [](const RegistrationProblem& p) { return !p.initial.has_value(); });
    if (without_start > 0 && !Perturbs(args)) {
      std::fprintf(stderr,
                   "mlsreg eval: warning: %s: %ld of %zu problems have no init column and no "
                   "--perturb-* flag is given, so they start at the ground truth: their errors "
                   "only show how far a method drifts from it (give --perturb-angle and "
                   "--perturb-translation to start elsewhere)\n",
                   path.c_str(), static_cast<long>(without_start), manifest->problems.size());
    }
    for (const std::string& c : manifest->extra_columns) {
      if (std::find(extra_columns.begin(), extra_columns.end(), c) == extra_columns.end()) {
        extra_columns.push_back(c);
      }
    }
    auto outcomes = RunEvaluation(
        *manifest, options, [&](const ProblemOutcome& o, std::size_t done, std::size_t total) {
          const RegistrationProblem& p = manifest->problems[o.problem_index];
          progress.Update(
              done, total,
              o.status.ok()
                  ? absl::StrFormat("%s %s: %.3f d", p.id, MethodName(o.method), o.error.rmse_d)
                  : absl::StrFormat("%s %s: ERROR %s", p.id, MethodName(o.method),
                                    std::string(o.status.message())));
        });
    if (!outcomes.ok()) return Fail(outcomes.status());
    for (const ProblemOutcome& o : *outcomes) {
      const RegistrationProblem& p = manifest->problems[o.problem_index];
      std::vector<std::string> f = {path, p.id, std::string(MethodName(o.method)), p.source_path,
                                    p.target_path};
      ++runs[o.method];
      if (!o.status.ok()) {
        ++errors[o.method];
        failures.push_back(absl::StrFormat("mlsreg eval: %s (%s, %s): %s", p.id,
                                           MethodName(o.method), path,
                                           std::string(o.status.message())));
        f.push_back(std::string(o.status.message()));
        f.resize(std::size(kFixedColumns) - 1);
      } else {
        const RegistrationResult& r = o.result;
        f.push_back("ok");
        for (double v : {o.error.rmse_d}) f.push_back(absl::StrFormat("%.6g", v));
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
        } else {
          f.insert(f.end(), 6, std::string());
        }
        if (const std::optional<AutoReport>& a = r.auto_report; a && !a->candidates.empty()) {
          f.push_back(absl::StrFormat("%d", a->chosen));
          f.push_back(absl::StrFormat("%zu", a->candidates.size()));
          f.push_back(a->early_exit ? "1" : "0");
          f.push_back(absl::StrFormat("%.4f", a->candidates[0].score.inlier_fraction));
          f.push_back(absl::StrFormat("%.4f", a->verification.inlier_fraction));
          f.push_back(absl::StrFormat("%.4f", a->verification.rmse_d));
          f.push_back(absl::StrFormat("%.4f", a->verification.inlier_distance_d));
        } else {
          f.insert(f.end(), 7, std::string());
        }
        rmse_by_method[o.method].push_back(o.error.rmse_d);
        time_by_method[o.method].push_back(r.timings.total);
        successes[o.method] += o.error.success;
      }
      f.push_back(args.label);
      for (const std::string& c : extra_columns) {
        std::string value;
        for (const auto& [name, v] : p.extra) {
          if (name == c) value = v;
        }
        f.push_back(value);
      }
      std::vector<std::string> quoted;
      for (const std::string& s : f) quoted.push_back(CsvField(s));
      rows.push_back(absl::StrJoin(quoted, ","));
    }
  }

  std::vector<std::string> header(std::begin(kFixedColumns), std::end(kFixedColumns));
  header.insert(header.end(), extra_columns.begin(), extra_columns.end());
  const std::string csv = absl::StrJoin(header, ",") + "\n" + absl::StrJoin(rows, "\n") + "\n";
  if (args.out.empty() || args.out == "-") {
    std::fputs(csv.c_str(), stdout);
  } else {
    std::ofstream out(args.out);
    out << csv;
    if (!out) return Fail(absl::UnavailableError("cannot write '" + args.out + "'"));
  }

  for (const std::string& line : failures) std::fprintf(stderr, "%s\n", line.c_str());
  std::FILE* summary = args.out.empty() || args.out == "-" ? stderr : stdout;
  std::fprintf(summary, "%-18s %5s %9s %7s %14s %14s %12s\n", "method", "runs", "success", "errors",
               "median RMSE/d", "mean RMSE/d", "median time");
  for (Method m : options.methods) {
    const std::vector<double>& e = rmse_by_method[m];
    double mean = 0.0;
    for (double v : e) mean += v;
    if (!e.empty()) mean /= static_cast<double>(e.size());
    std::fprintf(summary, "%-18s %5d %4d/%-4d %7d %s %s %s\n", std::string(MethodName(m)).c_str(),
                 runs[m], successes[m], runs[m], errors[m],
                 Cell(e, absl::StrFormat("%.4f", Median(e)), 14).c_str(),
                 Cell(e, absl::StrFormat("%.4f", mean), 14).c_str(),
                 Cell(e, absl::StrFormat("%.3f s", Median(time_by_method[m])), 12).c_str());
  }
  if (!failures.empty()) {
    std::fprintf(summary,
                 "(%zu runs could not run, see above: the RMSE and time columns are over the "
                 "runs that did)\n",
                 failures.size());
  }
  if (!args.json.empty()) {
    nlohmann::json methods = nlohmann::json::array();
    for (Method m : options.methods) {
      const bool ran = !rmse_by_method[m].empty();
      methods.push_back(
          {{"method", std::string(MethodName(m))},
           {"runs", runs[m]},
           {"successes", successes[m]},
           {"errors", errors[m]},
           {"median_rmse_d", ran ? nlohmann::json(Median(rmse_by_method[m])) : nullptr},
           {"median_time_s", ran ? nlohmann::json(Median(time_by_method[m])) : nullptr}});
    }
    std::ofstream out(args.json);
    out << nlohmann::json{{"methods", methods}}.dump(2) << "\n";
    if (!out) return Fail(absl::UnavailableError("cannot write --json file '" + args.json + "'"));
  }
  for (Method m : options.methods) {
    if (successes[m] != runs[m]) return kExitMissed;
  }
  return kExitOk;
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
  args->flags.AddTo(*cmd, /*method_flag=*/false);
  return [args] { return RunEval(*args); };
}

}  // namespace mlsreg::cli
