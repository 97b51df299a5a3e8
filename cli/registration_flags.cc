#include "cli/registration_flags.h"

namespace mlsreg::cli {

void RegistrationFlags::AddTo(CLI::App& app, bool method_flag) {
  if (method_flag) {
    std::string names;
    for (Method m : AllMethods())
      names += (names.empty() ? "" : " | ") + std::string(MethodName(m));
    app.add_option("--method", method_, names)->capture_default_str();
  }
  app.add_option("--samples", options_.num_samples, "random source samples")->capture_default_str();
  app.add_option("--seed", options_.seed, "subsampling seed")->capture_default_str();
  app.add_option("--max-iterations", options_.max_iterations, "ICP iterations")
      ->capture_default_str();
  app.add_option("--convergence", options_.convergence_d,
                 "stop when no sample moves more than this (units of d)")
      ->capture_default_str();
  app.add_option("--stall", options_.stall_d,
                 "also stop when the last 8 poses stay within this (units of d; 0 disables)")
      ->capture_default_str();
  app.add_option("--tangential-damping", options_.tangential_damping,
                 "point-to-plane with MLS/RC partners: weight damping sliding along the surface")
      ->capture_default_str();
  app.add_option("--mls-radius", options_.mls.radius_d, "MLS support radius r (units of d)")
      ->capture_default_str();
  app.add_option("--mls-degree", options_.mls.polynomial_degree, "MLS polynomial degree (0-3)")
      ->capture_default_str();
  app.add_option("--mls-max-iterations", options_.mls.max_iterations,
                 "iterations of one MLS projection")
      ->capture_default_str();
  app.add_flag("!--no-warm-start", options_.mls.warm_start,
               "start every MLS projection from the query itself");
  app.add_option("--mls-far-queries", far_queries_,
                 "queries with < 3 target samples within r: seed-until-converged (from the "
                 "nearest sample, then dropped once converged) | seed | drop (paper Alg. 1)")
      ->capture_default_str();
  app.add_option("--tau-n", options_.filter.min_normal_dot,
                 "normal filter: min <n1,n2> (-1 disables)")
      ->capture_default_str();
  app.add_option("--tau-h", options_.filter.min_curvature_ratio,
                 "curvature filter: min H1/H2 ratio (0 disables)")
      ->capture_default_str();
  app.add_option("--coarse-filters", coarse_filters_,
                 "filters of the MLS coarse phase: all | normal (tau-n only) | none")
      ->capture_default_str();
  app.add_option("--max-distance", options_.filter.max_distance_d,
                 "reject correspondences farther than this (units of d; 0 disables)")
      ->capture_default_str();
  app.add_option("--sicp-p", options_.sicp.p, "Sparse ICP lp exponent")->capture_default_str();
  app.add_option("--sicp-outer", options_.sicp.max_outer, "ADMM iterations per ICP iteration")
      ->capture_default_str();
  app.add_option("--sicp-unit", options_.sicp_length_unit_d, "Sparse ICP length unit (units of d)")
      ->capture_default_str();
  app.add_option("--gicp-neighbors", options_.gicp.covariance_neighbors,
                 "G-ICP: neighbours per covariance")
      ->capture_default_str();
  app.add_option("--gicp-epsilon", options_.gicp.epsilon, "G-ICP: plane-to-plane epsilon")
      ->capture_default_str();
  app.add_option("--gicp-max-distance", options_.gicp.max_distance_d,
                 "G-ICP: max correspondence distance (units of d)")
      ->capture_default_str();
  app.add_option("--fgr-radius", options_.fgr.feature_radius_d, "FGR: FPFH radius (units of d)")
      ->capture_default_str();
  app.add_option("--fgr-samples", options_.fgr.samples, "FGR: samples per cloud with features")
      ->capture_default_str();
  app.add_option("--sicp-metric", metric_, "point-to-plane | point-to-point")
      ->capture_default_str();
}

absl::StatusOr<RegistrationOptions> RegistrationFlags::ToOptions() const {
  RegistrationOptions options = options_;
  auto method = ParseMethod(method_);
  if (!method.ok()) return method.status();
  options.method = *method;
  if (metric_ == "point-to-plane") {
    options.sicp.metric = SicpMetric::kPointToPlane;
  } else if (metric_ == "point-to-point") {
    options.sicp.metric = SicpMetric::kPointToPoint;
  } else {
    return absl::InvalidArgumentError("sicp-metric: must be point-to-plane or point-to-point");
  }
  if (far_queries_ == "seed-until-converged") {
    options.mls.far_queries = FarQueryPolicy::kSeedUntilConverged;
  } else if (far_queries_ == "seed") {
    options.mls.far_queries = FarQueryPolicy::kSeed;
  } else if (far_queries_ == "drop") {
    options.mls.far_queries = FarQueryPolicy::kDrop;
  } else {
    return absl::InvalidArgumentError(
        "mls-far-queries: must be seed-until-converged, seed or drop");
  }
  auto coarse = ParseCoarsePhaseFilters(coarse_filters_);
  if (!coarse.ok())
    return absl::InvalidArgumentError("coarse-filters: must be all, normal or none");
  options.filter.coarse_phase = *coarse;
  if (absl::Status s = ValidateOptions(options); !s.ok()) return s;
  return options;
}

}  // namespace mlsreg::cli
