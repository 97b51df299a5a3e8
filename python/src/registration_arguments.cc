#include "python/src/registration_arguments.h"

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>

#include <algorithm>
#include <map>
#include <string>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "mlsreg/registration/method.h"
#include "mlsreg/registration/parameters.h"
#include "python/src/status_errors.h"

namespace mlsreg::python {
namespace {

// The CLI flag as a keyword: "--tau-n" is tau_n.
std::string FlagKeyword(const ParameterSpec& spec) {
  std::string keyword(spec.flag);
  std::replace(keyword.begin(), keyword.end(), '-', '_');
  return keyword;
}

// A parameter by any of its Python names: the wire field (min_normal_dot), the path in
// RegistrationOptions (filter.min_normal_dot) or the CLI flag with '_' for '-' (tau_n).
// `inverted` is set for a "no-" flag of a bool (no_warm_start=True is mls_warm_start=False).
const ParameterSpec* FindByPythonName(std::string_view name, bool* inverted) {
  for (const ParameterSpec& spec : ParameterTable()) {
    if (spec.wire_field == name || spec.name == name) {
      *inverted = false;
      return &spec;
    }
    if (FlagKeyword(spec) == name) {
      *inverted = spec.type == ParameterType::kBool && spec.flag.starts_with("no-");
      return &spec;
    }
  }
  return nullptr;
}

// The value as the table's text form, so that parsing, ranges and messages are the library's.
std::string ParameterText(py::handle value) {
  if (value.is_none()) return "auto";
  if (py::isinstance<py::bool_>(value)) return value.cast<bool>() ? "true" : "false";
  if (py::isinstance<py::str>(value)) return value.cast<std::string>();
  if (py::isinstance<py::float_>(value)) return py::repr(value).cast<std::string>();
  return py::str(value).cast<std::string>();  // ints, NumPy scalars
}

py::dict ScoreToPython(const VerificationScore& s) {
  py::list direction;
  for (int k = 0; k < 6; ++k) direction.append(s.worst_direction[k]);
  return py::dict(
      py::arg("verified") = s.verified(), py::arg("verdict") = std::string(VerdictName(s.verdict)),
      py::arg("samples") = s.samples, py::arg("covered") = s.covered, py::arg("hidden") = s.hidden,
      py::arg("seen_through") = s.seen_through, py::arg("sides_judged") = s.sides_judged,
      py::arg("seen_from_behind") = s.seen_from_behind, py::arg("inliers") = s.inliers,
      py::arg("inlier_fraction") = s.inlier_fraction,
      py::arg("explained_fraction") = s.explained_fraction, py::arg("rmse_d") = s.rmse_d,
      py::arg("inlier_distance_d") = s.inlier_distance_d,
      py::arg("inlier_distance") = s.inlier_distance, py::arg("worst_direction") = direction,
      py::arg("worst_direction_text") = s.WorstDirectionText(),
      py::arg("worst_direction_fraction") = s.worst_direction_fraction,
      py::arg("worst_direction_samples") = s.worst_direction_samples,
      py::arg("worst_direction_strength") = s.worst_direction_strength,
      py::arg("worst_direction_error") = s.worst_direction_error,
      py::arg("weakest_translation") = py::make_tuple(
          s.weakest_translation.x(), s.weakest_translation.y(), s.weakest_translation.z()),
      py::arg("weakest_translation_strength") = s.weakest_translation_strength,
      py::arg("residual_scale") = s.residual_scale, py::arg("pull_fraction") = s.pull_fraction,
      py::arg("pull_rotation_deg") = s.pull_rotation_deg,
      py::arg("pull_translation") = s.pull_translation,
      py::arg("pull_displacement") = s.pull_displacement,
      py::arg("settle_displacement") = s.settle_displacement,
      py::arg("coherent_residual") = s.coherent_residual, py::arg("noise") = s.noise,
      py::arg("normal_angle_median_deg") = s.normal_angle_median_deg,
      py::arg("edge_samples") = s.edge_samples,
      py::arg("pose_covariance") = s.pose_covariance
                                       ? py::cast(Eigen::Matrix<double, 6, 6>(*s.pose_covariance))
                                       : py::object(py::none()),
      py::arg("pose_rotation_sigma_deg") = s.pose_rotation_sigma_deg,
      py::arg("pose_translation_sigma") = s.pose_translation_sigma);
}

py::dict CandidateToPython(const AutoCandidate& c) {
  return py::dict(py::arg("origin") = std::string(CandidateOriginName(c.origin)),
                  py::arg("start") = Matrix4(c.start), py::arg("refined") = Matrix4(c.refined),
                  py::arg("feature_inliers") = c.feature_inliers,
                  py::arg("iterations") = c.iterations, py::arg("score") = ScoreToPython(c.score),
                  py::arg("seconds") = c.seconds, py::arg("in_start_basin") = c.in_start_basin);
}

py::dict AutoToPython(const AutoReport& report) {
  py::list candidates;
  for (const AutoCandidate& c : report.candidates) candidates.append(CandidateToPython(c));
  const AutoStageTimings& t = report.timings;
  const FinishReport& f = report.finish;
  const py::dict finish(py::arg("kind") = std::string(FinishKindName(f.kind)),
                        py::arg("noise_d") = f.noise_d, py::arg("crossover_d") = f.crossover_d,
                        py::arg("samples") = f.samples, py::arg("iterations") = f.iterations,
                        py::arg("kept") = f.kept, py::arg("moved") = f.moved,
                        py::arg("contradicted") = f.contradicted, py::arg("seconds") = f.seconds);
  return py::dict(
      py::arg("candidates") = candidates, py::arg("chosen") = report.chosen,
      py::arg("verified") = report.verified,
      py::arg("verification") = ScoreToPython(report.verification),
      py::arg("early_exit") = report.early_exit,
      py::arg("polished_by_settling") = report.polished_by_settling,
      py::arg("feature_matches") = report.feature_matches,
      py::arg("timings") = py::dict(py::arg("start") = t.start, py::arg("global") = t.global,
                                    py::arg("candidates") = t.candidates,
                                    py::arg("final") = t.final, py::arg("rivals") = t.rivals),
      py::arg("finish") = finish,
      py::arg("rival") =
          report.rival ? py::object(py::int_(*report.rival)) : py::object(py::none()));
}

}  // namespace

GivenLength LengthFromPython(py::handle value, std::string_view field) {
  if (py::isinstance<py::bool_>(value) || value.is_none()) {
    throw py::value_error(
        absl::StrCat(std::string(field), ": a number (in d) or a length such as \"5m\""));
  }
  return ValueOrThrow(ParseLength(ParameterText(value), field));
}

RegistrationOptions OptionsFromPython(std::string_view method, const py::dict& params) {
  RegistrationOptions options;
  options.method = ValueOrThrow(ParseMethod(method));
  std::map<const ParameterSpec*, std::string> given;  // the name each parameter was given by
  for (const auto& [key, value] : params) {
    const std::string name = py::str(key).cast<std::string>();
    bool inverted = false;
    const ParameterSpec* spec = FindByPythonName(name, &inverted);
    if (spec == nullptr) {
      std::vector<std::string> names;
      for (const ParameterSpec& s : ParameterTable()) {
        names.push_back(absl::StrCat(std::string(s.wire_field), " (", FlagKeyword(s), ")"));
      }
      throw StatusError(absl::InvalidArgumentError(
          absl::StrCat(name, ": not a registration parameter; the parameters are ",
                       absl::StrJoin(names, ", "))));
    }
    if (const auto [it, fresh] = given.emplace(spec, name); !fresh) {
      throw StatusError(absl::InvalidArgumentError(
          absl::StrCat(name, " and ", it->second, " name the same parameter (",
                       std::string(spec->wire_field), "): give one")));
    }
    if (inverted) {
      ParameterValue parsed = ValueOrThrow(spec->Parse(ParameterText(value), name));
      spec->set(options, !std::get<bool>(parsed));
    } else {
      ThrowIfError(SetParameterFromText(options, *spec, ParameterText(value), name));
    }
  }
  return options;
}

Matrix4 TransformFromPython(py::handle object, std::string_view field) {
  if (object.is_none()) return Matrix4::Identity();
  py::array array = py::module_::import("numpy").attr("asarray")(object);
  if (array.dtype().kind() != 'f' && array.dtype().kind() != 'i') {
    throw StatusError(absl::InvalidArgumentError(
        absl::StrCat(std::string(field), ": a 4x4 array of numbers is needed")));
  }
  if (array.ndim() != 2 || array.shape(0) != 4 || array.shape(1) != 4) {
    throw StatusError(
        absl::InvalidArgumentError(absl::StrCat(std::string(field), ": the shape must be (4, 4)")));
  }
  const Matrix4 m = array.cast<Matrix4>();
  ThrowIfError(CheckRigid(m, field));
  return Orthonormalize(m);
}

py::dict ReportToPython(const IterationReport& r) {
  return py::dict(
      py::arg("iteration") = r.iteration, py::arg("stage") = std::string(StageName(r.stage)),
      py::arg("candidate") = r.candidate, py::arg("rmse") = r.rmse, py::arg("rmse_d") = r.rmse_d,
      py::arg("matched") = r.counts.matched, py::arg("rejected_normal") = r.counts.rejected_normal,
      py::arg("rejected_curvature") = r.counts.rejected_curvature,
      py::arg("rejected_distance") = r.counts.rejected_distance,
      py::arg("invalid") = r.counts.invalid, py::arg("admm_iterations") = r.admm_iterations,
      py::arg("elapsed_seconds") = r.elapsed_seconds, py::arg("transform") = Matrix4(r.transform));
}

py::dict ResultToPython(const RegistrationResult& result) {
  py::list trace;
  for (const IterationReport& r : result.trace) trace.append(ReportToPython(r));
  const PhaseTimings& t = result.timings;
  py::dict d(
      py::arg("transform") = Matrix4(result.transform), py::arg("converged") = result.converged,
      py::arg("termination") = std::string(TerminationName(result.termination)),
      py::arg("iterations") = result.iterations, py::arg("trace") = trace,
      py::arg("timings") =
          py::dict(py::arg("preprocessing") = t.preprocessing,
                   py::arg("subsampling") = t.subsampling, py::arg("matching") = t.matching,
                   py::arg("optimisation") = t.optimisation, py::arg("total") = t.total),
      py::arg("sampling_distance") = result.sampling_distance,
      py::arg("num_samples") = result.num_samples, py::arg("mls_radius_d") = result.mls_radius_d,
      py::arg("mls_radius_auto") = result.mls_radius_auto,
      py::arg("target_noise_d") = result.target_noise_d,
      py::arg("source_noise_d") = result.source_noise_d);
  d["auto"] = result.auto_report ? py::object(AutoToPython(*result.auto_report)) : py::none();
  d["verification"] =
      result.verification ? py::object(ScoreToPython(*result.verification)) : py::none();
  d["rival"] = result.rival ? py::object(CandidateToPython(*result.rival)) : py::none();
  const ScaleReport& sc = result.scales;
  py::dict scales(
      py::arg("mean_spacing") = sc.mean_spacing, py::arg("median_spacing") = sc.median_spacing,
      py::arg("spacing_p90") = sc.spacing_p90, py::arg("extent") = sc.extent,
      py::arg("working_voxel") = sc.working_voxel, py::arg("capture_start") = sc.capture_start,
      py::arg("capture_end") = sc.capture_end, py::arg("mls_radius") = sc.mls_radius,
      py::arg("verification_band") = sc.verification_band);
  py::list user_lengths;
  for (const UserLength& length : sc.user_lengths) {
    user_lengths.append(py::dict(py::arg("parameter") = length.parameter,
                                 py::arg("value") = length.value,
                                 py::arg("value_d") = length.value_d));
  }
  scales["user_lengths"] = user_lengths;
  scales["sensor"] =
      sc.sensor ? py::object(py::make_tuple(sc.sensor->x(), sc.sensor->y(), sc.sensor->z()))
                : py::none();
  d["scales"] = scales;
  return d;
}

}  // namespace mlsreg::python
