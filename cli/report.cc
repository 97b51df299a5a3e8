#include "cli/report.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "absl/strings/str_format.h"

namespace mlsreg::cli {
namespace {
nlohmann::json MatrixJson(const Matrix4& m) {
  nlohmann::json values = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) values.push_back(m(r, c));
  }
  return values;
}

// Which finish polished auto's result and why (registration/finish.h); `verified`: the
// result's verdict; `settled`: the result is where the verification's settling put it
// (AutoReport::polished_by_settling); d: the target's.
std::string FinishLine(const FinishReport& f, bool verified, bool settled, double d) {
  if (f.kind == FinishKind::kNone && settled) {
    return "auto finish: none (the settled pose verified: the settling was the last step)\n";
  }
  if (f.kind == FinishKind::kNone) {
    // Only a result that neither verified nor was pulled skips an enabled finish.
    return verified ? "auto finish: none (switched off)\n"
                    : "auto finish: none (the result did not verify, nor is it only pulled)\n";
  }
  const bool clean = f.kind == FinishKind::kPlaneToPlane;
  return absl::StrFormat(
      "auto finish: %s (noise %.2f d %s %.2f d, the MLS fit's floor), %d points, %d its, "
      "moved %.3f d: %s\n",
      FinishKindName(f.kind), f.noise_d, clean ? "<" : ">=", f.crossover_d, f.samples, f.iterations,
      d > 0.0 ? f.moved / d : 0.0,
      f.kept           ? "kept (verified)"
      : f.contradicted ? "not kept (did not verify), and it moved the verified pose beyond the "
                         "verdict's settling bound: the refined pose is returned pulled"
                       : "not kept (did not verify; the refined pose is returned)");
}
}  // namespace

std::string FormatIteration(const IterationReport& r) {
  std::string stage;
  if (r.stage == Stage::kGlobal) {
    return absl::StrFormat("[global] %d feature matches, candidates found  %7.3f s",
                           r.counts.matched, r.elapsed_seconds);
  }
  if (r.stage == Stage::kCandidate || r.stage == Stage::kRival) {
    stage = absl::StrFormat("[%s %d] ", StageName(r.stage), r.candidate);
  } else if (r.stage != Stage::kSingle) {
    stage = absl::StrFormat("[%s] ", StageName(r.stage));
  }
  return stage +
         absl::StrFormat(
             "iter %3d  rmse %8.4f d  matched %5d  rejected normal %4d curvature %4d distance %4d  "
             "invalid %4d  admm %2d  %7.3f s",
             r.iteration, r.rmse_d, r.counts.matched, r.counts.rejected_normal,
             r.counts.rejected_curvature, r.counts.rejected_distance, r.counts.invalid,
             r.admm_iterations, r.elapsed_seconds);
}

std::string FormatVerification(const VerificationScore& v) {
  const std::string evidence = absl::StrFormat(
      "%.1f %% of the overlap (%d of %d covered samples) within %.4g (%.2f d) of the target's "
      "surface, RMSE %.3f d; weakest direction: %s, standard error %.3g, %.1f %% of its %d "
      "samples agree; pull: a step of %.3g deg and %.3g would remove %.1f %% of the residuals, "
      "settling moves the samples %.3g; neighbours share %.3g of their residuals%s%s%s",
      100.0 * v.inlier_fraction, v.inliers, v.covered, v.inlier_distance, v.inlier_distance_d,
      v.rmse_d, v.WorstDirectionText(), v.worst_direction_error, 100.0 * v.worst_direction_fraction,
      v.worst_direction_samples, v.pull_rotation_deg, v.pull_translation, 100.0 * v.pull_fraction,
      v.settle_displacement, v.coherent_residual,
      v.hidden > 0 || v.seen_through > 0
          ? absl::StrFormat("; of %d samples, %d lie where the target's sensor could not see, %d "
                            "where it saw through them",
                            v.samples, v.hidden, v.seen_through)
          : std::string(),
      v.sides_judged > 0
          ? absl::StrFormat("; of %d inliers whose surface both sensors saw clearly, %d the "
                            "source's sensor saw from behind",
                            v.sides_judged, v.seen_from_behind)
          : std::string(),
      v.pose_covariance
          ? absl::StrFormat("; pose uncertainty (1 sigma, least certain direction): %.3g deg, "
                            "%.3g at the overlap's centre",
                            v.pose_rotation_sigma_deg, v.pose_translation_sigma)
          : std::string("; pose uncertainty: unbounded (some direction has too little evidence)"));
  if (v.verified()) return "verification: verified: " + evidence;
  return absl::StrFormat("verification: NOT VERIFIED (%s; do not trust the transform): %s",
                         VerdictName(v.verdict), evidence);
}

// Where the rival lies against the result (scored `score`), and how much of the source it
// explains.
std::string FormatRival(const AutoCandidate& rival, const VerificationScore& score,
                        const Matrix4& result) {
  const Eigen::Matrix3d turn =
      result.topLeftCorner<3, 3>().transpose() * rival.refined.topLeftCorner<3, 3>();
  const double angle_deg =
      std::acos(std::clamp((turn.trace() - 1.0) / 2.0, -1.0, 1.0)) * 180.0 / M_PI;
  const double shift = (rival.refined.col(3) - result.col(3)).head<3>().norm();
  const double explained = score.visible_explained_fraction();
  const double share = explained > 0.0 ? rival.score.visible_explained_fraction() / explained : 0.0;
  return absl::StrFormat(
      "rival: a pose %.4g away (turned %.3g deg) explains %.1f %% as large a share of what the "
      "target's sensor could see of the source: the data do not tell the two poses apart "
      "(weakest direction: %s)\n",
      shift, angle_deg, 100.0 * share, score.WorstDirectionText());
}

nlohmann::json RivalJson(const AutoCandidate& rival) {
  return {{"start", MatrixJson(rival.start)},
          {"refined", MatrixJson(rival.refined)},
          {"iterations", rival.iterations},
          {"score", VerificationJson(rival.score)},
          {"seconds", rival.seconds}};
}

std::string FormatTermination(const RegistrationResult& result, int max_iterations) {
  if (result.termination == Termination::kMaxIterations) {
    return absl::StrFormat("max_iterations (%d per phase) after %d iterations in total",
                           max_iterations, result.iterations);
  }
  return absl::StrFormat("%s after %d iterations", TerminationName(result.termination),
                         result.iterations);
}

std::string FormatResult(const RegistrationResult& result, const std::optional<PoseError>& error,
                         int max_iterations) {
  std::string out = absl::StrFormat("result: %s in %.3f s (d = %.6g)\n",
                                    FormatTermination(result, max_iterations), result.timings.total,
                                    result.sampling_distance);
  if (result.mls_radius_d > 0.0) {
    out += result.mls_radius_auto
               ? absl::StrFormat(
                     "MLS radius: %.2f d (auto: estimated noise %.2f d on the target, %.2f d on "
                     "the source)\n",
                     result.mls_radius_d, result.target_noise_d, result.source_noise_d)
               : absl::StrFormat("MLS radius: %.2f d (as given)\n", result.mls_radius_d);
  }
  out += "transform (source -> target, row-major):\n";
  for (int r = 0; r < 4; ++r) {
    out += absl::StrFormat("  % .9f % .9f % .9f % .9f\n", result.transform(r, 0),
                           result.transform(r, 1), result.transform(r, 2), result.transform(r, 3));
  }
  if (const std::optional<AutoReport>& a = result.auto_report; a && !a->candidates.empty()) {
    out += absl::StrFormat(
        "auto: candidate %d of %zu chosen%s%s\n", a->chosen, a->candidates.size(),
        a->early_exit ? " (the start verified: no global stage)" : "",
        a->polished_by_settling ? "; then moved where the verification's settling put it" : "");
    out += absl::StrFormat(
        "auto stages: start %.3f s, global %.3f s (%d feature matches), candidates %.3f s, final "
        "%.3f s, rival search %.3f s\n",
        a->timings.start, a->timings.global, a->feature_matches, a->timings.candidates,
        a->timings.final, a->timings.rivals);
    for (std::size_t k = 0; k < a->candidates.size(); ++k) {
      const AutoCandidate& c = a->candidates[k];
      out += absl::StrFormat(
          "  candidate %zu %-6s  %-19s overlap on surface %5.1f %%  RMSE %7.3f d  %3d its  "
          "%6.3f s%s\n",
          k, CandidateOriginName(c.origin),
          !c.in_start_basin                     ? VerdictName(c.score.verdict)
          : c.origin == CandidateOrigin::kRival ? std::string_view("back at the result")
                                                : std::string_view("start's basin"),
          100.0 * c.score.inlier_fraction, c.score.rmse_d, c.iterations, c.seconds,
          static_cast<int>(k) == a->chosen               ? "  <- chosen"
          : a->rival && static_cast<int>(k) == *a->rival ? "  <- rival: explains as much elsewhere"
                                                         : "");
    }
    out += FinishLine(a->finish, a->verified, a->polished_by_settling, result.sampling_distance);
  }
  if (result.rival && result.verification) {
    out += FormatRival(*result.rival, *result.verification, result.transform);
  }
  const ScaleReport& sc = result.scales;
  if (sc.working_voxel > 0.0) {
    out += absl::StrFormat(
        "scales (units of the clouds, from the data): spacing mean %.4g, median %.4g, 90th "
        "percentile %.4g; extent %.4g; working voxel %.4g",
        sc.mean_spacing, sc.median_spacing, sc.spacing_p90, sc.extent, sc.working_voxel);
    if (sc.capture_start > 0.0) {
      out += absl::StrFormat("; capture %.4g -> %.4g", sc.capture_start, sc.capture_end);
    }
    if (sc.mls_radius > 0.0) out += absl::StrFormat("; MLS radius %.4g", sc.mls_radius);
    if (sc.verification_band > 0.0) {
      out += absl::StrFormat("; verification band %.4g", sc.verification_band);
    }
    if (sc.sensor) {
      out += absl::StrFormat("; the target's sensor at (%.4g, %.4g, %.4g)", sc.sensor->x(),
                             sc.sensor->y(), sc.sensor->z());
    }
    for (const UserLength& length : sc.user_lengths) {
      out += absl::StrFormat("; given %s %.4g = %.4g d", length.parameter, length.value,
                             length.value_d);
    }
    out += "\n";
  }
  if (result.verification) out += FormatVerification(*result.verification) + "\n";
  if (error) {
    out += absl::StrFormat(
        "against ground truth: RMSE %.4f d (%s at 5 d), rotation error %.4f deg, translation "
        "error %.4f d\n",
        error->rmse_d, error->success ? "success" : "FAILURE", error->rotation_deg,
        error->translation_d);
  }
  return out;
}

ProgressPrinter::ProgressPrinter() : terminal_(isatty(fileno(stderr))) {}

void ProgressPrinter::Update(std::size_t done, std::size_t total, const std::string& line) {
  if (terminal_) {
    const int width = 30;
    const int filled = static_cast<int>(width * done / std::max<std::size_t>(total, 1));
    std::fprintf(stderr, "\r[%s%s] %zu/%zu %-60.60s", std::string(filled, '#').c_str(),
                 std::string(width - filled, '.').c_str(), done, total, line.c_str());
    if (done == total) std::fprintf(stderr, "\n");
  } else {
    std::fprintf(stderr, "[%zu/%zu] %s\n", done, total, line.c_str());
  }
  std::fflush(stderr);
}

nlohmann::json IterationJson(const IterationReport& r) {
  return {{"iteration", r.iteration},
          {"rmse", r.rmse},
          {"rmse_d", r.rmse_d},
          {"matched", r.counts.matched},
          {"rejected_normal", r.counts.rejected_normal},
          {"rejected_curvature", r.counts.rejected_curvature},
          {"rejected_distance", r.counts.rejected_distance},
          {"invalid", r.counts.invalid},
          {"admm_iterations", r.admm_iterations},
          {"elapsed_seconds", r.elapsed_seconds},
          {"stage", std::string(StageName(r.stage))},
          {"candidate", r.candidate},
          {"transform", MatrixJson(r.transform)}};
}

nlohmann::json PoseCovarianceJson(const std::optional<Eigen::Matrix<double, 6, 6>>& covariance) {
  if (!covariance) return nullptr;
  nlohmann::json values = nlohmann::json::array();
  for (int row = 0; row < 6; ++row) {
    for (int col = 0; col < 6; ++col) values.push_back((*covariance)(row, col));
  }
  return values;
}

nlohmann::json VerificationJson(const VerificationScore& v) {
  nlohmann::json direction = nlohmann::json::array();
  for (int k = 0; k < 6; ++k) direction.push_back(v.worst_direction[k]);
  return {{"verified", v.verified()},
          {"verdict", std::string(VerdictName(v.verdict))},
          {"samples", v.samples},
          {"covered", v.covered},
          {"hidden", v.hidden},
          {"seen_through", v.seen_through},
          {"sides_judged", v.sides_judged},
          {"seen_from_behind", v.seen_from_behind},
          {"inliers", v.inliers},
          {"inlier_fraction", v.inlier_fraction},
          {"explained_fraction", v.explained_fraction},
          {"rmse_d", v.rmse_d},
          {"inlier_distance", v.inlier_distance},
          {"inlier_distance_d", v.inlier_distance_d},
          {"noise", v.noise},
          {"residual_scale", v.residual_scale},
          {"pull_fraction", v.pull_fraction},
          {"pull_rotation_deg", v.pull_rotation_deg},
          {"pull_translation", v.pull_translation},
          {"pull_displacement", v.pull_displacement},
          {"settle_displacement", v.settle_displacement},
          {"coherent_residual", v.coherent_residual},
          {"worst_direction", direction},
          {"worst_direction_text", v.WorstDirectionText()},
          {"worst_direction_fraction", v.worst_direction_fraction},
          {"worst_direction_samples", v.worst_direction_samples},
          {"worst_direction_strength", v.worst_direction_strength},
          {"worst_direction_error", v.worst_direction_error},
          {"weakest_translation",
           {v.weakest_translation.x(), v.weakest_translation.y(), v.weakest_translation.z()}},
          {"weakest_translation_strength", v.weakest_translation_strength},
          {"normal_angle_median_deg", v.normal_angle_median_deg},
          {"edge_samples", v.edge_samples},
          {"pose_covariance", PoseCovarianceJson(v.pose_covariance)},
          {"pose_rotation_sigma_deg", v.pose_rotation_sigma_deg},
          {"pose_translation_sigma", v.pose_translation_sigma}};
}

nlohmann::json ResultJson(std::string_view method, const RegistrationResult& result,
                          const std::optional<PoseError>& error) {
  nlohmann::json trace = nlohmann::json::array();
  for (const IterationReport& r : result.trace) trace.push_back(IterationJson(r));
  nlohmann::json j = {{"method", std::string(method)},
                      {"transform", MatrixJson(result.transform)},
                      {"converged", result.converged},
                      {"termination", std::string(TerminationName(result.termination))},
                      {"iterations", result.iterations},
                      {"sampling_distance", result.sampling_distance},
                      {"num_samples", result.num_samples},
                      {"mls_radius_d", result.mls_radius_d},
                      {"mls_radius_auto", result.mls_radius_auto},
                      {"target_noise_sigma_d", result.target_noise_d},
                      {"source_noise_sigma_d", result.source_noise_d},
                      {"timings",
                       {{"preprocessing", result.timings.preprocessing},
                        {"subsampling", result.timings.subsampling},
                        {"matching", result.timings.matching},
                        {"optimisation", result.timings.optimisation},
                        {"total", result.timings.total}}},
                      {"trace", trace}};
  if (result.verification) j["verification"] = VerificationJson(*result.verification);
  if (result.rival) j["rival"] = RivalJson(*result.rival);
  j["scales"] = {
      {"mean_spacing", result.scales.mean_spacing},
      {"median_spacing", result.scales.median_spacing},
      {"spacing_p90", result.scales.spacing_p90},
      {"extent", result.scales.extent},
      {"working_voxel", result.scales.working_voxel},
      {"capture_start", result.scales.capture_start},
      {"capture_end", result.scales.capture_end},
      {"mls_radius", result.scales.mls_radius},
      {"verification_band", result.scales.verification_band},
      {"sensor", result.scales.sensor
                     ? nlohmann::json::array({result.scales.sensor->x(), result.scales.sensor->y(),
                                              result.scales.sensor->z()})
                     : nlohmann::json()},
      {"user_lengths", nlohmann::json::array()}};
  for (const UserLength& length : result.scales.user_lengths) {
    j["scales"]["user_lengths"].push_back(
        {{"parameter", length.parameter}, {"value", length.value}, {"value_d", length.value_d}});
  }
  if (const std::optional<AutoReport>& a = result.auto_report) {
    nlohmann::json candidates = nlohmann::json::array();
    for (const AutoCandidate& c : a->candidates) {
      candidates.push_back({{"origin", std::string(CandidateOriginName(c.origin))},
                            {"start", MatrixJson(c.start)},
                            {"refined", MatrixJson(c.refined)},
                            {"feature_inliers", c.feature_inliers},
                            {"iterations", c.iterations},
                            {"score", VerificationJson(c.score)},
                            {"seconds", c.seconds},
                            {"in_start_basin", c.in_start_basin}});
    }
    j["auto"] = {{"verified", a->verified},
                 {"chosen", a->chosen},
                 {"early_exit", a->early_exit},
                 {"polished_by_settling", a->polished_by_settling},
                 {"feature_matches", a->feature_matches},
                 {"candidates", candidates},
                 {"stage_seconds",
                  {{"start", a->timings.start},
                   {"global", a->timings.global},
                   {"candidates", a->timings.candidates},
                   {"final", a->timings.final},
                   {"rivals", a->timings.rivals}}},
                 {"rival", a->rival ? nlohmann::json(*a->rival) : nlohmann::json(nullptr)},
                 {"finish",
                  {{"kind", std::string(FinishKindName(a->finish.kind))},
                   {"noise_d", a->finish.noise_d},
                   {"crossover_d", a->finish.crossover_d},
                   {"samples", a->finish.samples},
                   {"iterations", a->finish.iterations},
                   {"kept", a->finish.kept},
                   {"moved", a->finish.moved},
                   {"contradicted", a->finish.contradicted},
                   {"seconds", a->finish.seconds}}}};
  }
  if (error) {
    j["ground_truth"] = {{"rmse_d", error->rmse_d},
                         {"success", error->success},
                         {"rotation_error_deg", error->rotation_deg},
                         {"translation_error_d", error->translation_d}};
  }
  return j;
}

}  // namespace mlsreg::cli
