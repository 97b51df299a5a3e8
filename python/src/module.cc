// _mlsreg: the C++ side of the Python package (python/mlsreg/__init__.py wraps it). Every call
// into the library runs without the GIL, so Python threads register in parallel.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <functional>
#include <optional>
#include <string_view>

#include "absl/strings/str_cat.h"
#include "mlsreg/client/client.h"
#include "mlsreg/evaluation/metrics.h"
#include "mlsreg/geometry/kd_tree.h"
#include "mlsreg/geometry/sampling.h"
#include "mlsreg/geometry/target.h"
#include "mlsreg/io/io.h"
#include "mlsreg/io/pose_files.h"
#include "mlsreg/multiview/align_scans.h"
#include "mlsreg/multiview/merged_cloud.h"
#include "mlsreg/registration/method.h"
#include "mlsreg/registration/parameters.h"
#include "mlsreg/registration/registration.h"
#include "python/src/callback_bridge.h"
#include "python/src/cloud_arrays.h"
#include "python/src/registration_arguments.h"
#include "python/src/status_errors.h"

namespace mlsreg::python {
namespace {

using TargetPtr = std::shared_ptr<const Target>;

// A Target built once from Python data and reused by every registration against it.
struct TargetHandle {
  TargetPtr target;
};

// threads of a call: [1, 256], as the CLI's --threads.
void CheckThreads(int threads) {
  if (threads < 1 || threads > 256) {
    throw StatusError(
        absl::InvalidArgumentError(absl::StrCat("threads must be in [1, 256], not ", threads)));
  }
}

TargetPtr BuildTarget(PointCloud cloud, int threads) {
  CheckThreads(threads);
  TargetOptions options;
  options.threads = threads;
  absl::StatusOr<TargetPtr> built;
  {
    py::gil_scoped_release release;
    built = Target::Build(std::move(cloud), options);
  }
  if (!built.ok()) {
    throw StatusError(
        absl::Status(built.status().code(), absl::StrCat("target: ", built.status().message())));
  }
  return *std::move(built);
}

TargetHandle MakeTarget(py::object points, py::object normals, py::object intrinsics, int threads) {
  PointCloud cloud = normals.is_none() ? CloudFromPython(points, "target")
                                       : CloudFromArrays(points, normals, "target");
  if (!intrinsics.is_none()) cloud.intrinsics = IntrinsicsFromPython(intrinsics, "intrinsics");
  return TargetHandle{BuildTarget(std::move(cloud), threads)};
}

TargetPtr TargetFromPython(py::handle target, int threads) {
  if (py::isinstance<TargetHandle>(target)) return target.cast<const TargetHandle&>().target;
  return BuildTarget(CloudFromPython(target, "target"), threads);
}

py::dict Register(py::object source, py::object target, const std::string& method, py::object init,
                  py::object callback, int threads, const py::dict& params) {
  CheckThreads(threads);
  const RegistrationOptions options = OptionsFromPython(method, params);
  const Matrix4 initial = TransformFromPython(init, "init");
  PointCloud source_cloud = CloudFromPython(source, "source");
  const TargetPtr built = TargetFromPython(target, threads);
  CallbackBridge bridge(std::move(callback));
  absl::StatusOr<RegistrationResult> result;
  {
    py::gil_scoped_release release;
    ExecutionOptions execution;
    execution.threads = threads;
    result =
        mlsreg::Register(*built, source_cloud, initial, options, bridge.Callbacks(), execution);
  }
  bridge.RaiseIfFailed();
  return ResultToPython(ValueOrThrow(std::move(result)));
}

py::dict PoseErrorToPython(const PoseError& e) {
  return py::dict(py::arg("rmse_d") = e.rmse_d, py::arg("success") = e.success,
                  py::arg("rotation_deg") = e.rotation_deg,
                  py::arg("translation_d") = e.translation_d);
}

py::dict TargetInfoToPython(const TargetInfo& info) {
  return py::dict(
      py::arg("id") = info.id,
      py::arg("state") = std::string(TargetStateNames().NameOf(static_cast<int>(info.state))),
      py::arg("point_count") = info.point_count, py::arg("memory_bytes") = info.memory_bytes,
      py::arg("sampling_distance") = info.sampling_distance,
      py::arg("build_seconds") = info.build_seconds, py::arg("registrations") = info.registrations,
      py::arg("noise_sigma_d") = info.noise_sigma_d,
      py::arg("has_intrinsics") = info.has_intrinsics, py::arg("digest") = info.digest);
}

void BindLocal(py::module_& m) {
  m.def(
      "read_cloud",
      [](const std::string& path, const std::vector<std::string>& columns) {
        absl::StatusOr<CloudFile> file;
        {
          py::gil_scoped_release release;
          file = ReadCloudFile(path, ReadOptions{columns});
        }
        if (absl::IsNotFound(file.status())) {  // a missing file, as open() raises it
          PyErr_SetString(PyExc_FileNotFoundError, std::string(file.status().message()).c_str());
          throw py::error_already_set();
        }
        CloudFile read = ValueOrThrow(std::move(file));
        py::dict out = CloudToPython(read.cloud);
        out["notes"] = read.notes;
        return out;
      },
      py::arg("path"), py::arg("columns"));
  m.def(
      "write_cloud",
      [](const std::string& path, py::object cloud) {
        const PointCloud converted = CloudFromPython(cloud, "cloud");
        absl::Status written;
        {
          py::gil_scoped_release release;
          written = WritePointCloud(converted, path);
        }
        ThrowIfError(written);
      },
      py::arg("path"), py::arg("cloud"));

  py::class_<TargetHandle>(m, "Target", R"doc(A target cloud prepared once for many registrations.

Target(points, normals=None, intrinsics=None, threads=1) builds the target's kd-tree, its
sampling distance d (the unit of every *_d length), normals and surface variation, its noise
estimate, its MLS patches and its FPFH features (for method auto's global candidates). Build it
once and pass it to mlsreg.register as often as needed; it is immutable, so threads may share it.

points: (N, 3) or (N, 6) float array, an mlsreg.Cloud or an Open3D point cloud.
normals: ignored by registration (normals are estimated from the points).
intrinsics: {width, height, fx, fy, cx, cy} of an organised pinhole scan (rc-bl, rc-p).
threads: threads of the build, in [1, 256] (the result does not depend on it).

Attributes: size, points, normals (estimated), sampling_distance, noise_sigma_d, memory_bytes,
build_seconds, organised.)doc")
      .def(py::init(&MakeTarget), py::arg("points"), py::arg("normals") = py::none(),
           py::arg("intrinsics") = py::none(), py::arg("threads") = 1)
      .def_property_readonly("size",
                             [](const TargetHandle& t) { return t.target->points().size(); })
      .def("__len__", [](const TargetHandle& t) { return t.target->points().size(); })
      .def_property_readonly("points",
                             [](const TargetHandle& t) { return ToArray(t.target->points()); })
      .def_property_readonly(
          "normals", [](const TargetHandle& t) { return ToArray(t.target->surface().normals); })
      .def_property_readonly("sampling_distance",
                             [](const TargetHandle& t) { return t.target->sampling_distance(); })
      .def_property_readonly("noise_sigma_d",
                             [](const TargetHandle& t) { return t.target->noise().sigma_d; })
      .def_property_readonly("memory_bytes",
                             [](const TargetHandle& t) { return t.target->MemoryBytes(); })
      .def_property_readonly("build_seconds",
                             [](const TargetHandle& t) { return t.target->build_seconds(); })
      .def_property_readonly("organised",
                             [](const TargetHandle& t) { return t.target->grid() != nullptr; })
      .def("__repr__", [](const TargetHandle& t) {
        return py::str("mlsreg.Target({} points, d={:.6g}, noise={:.3g} d)")
            .format(t.target->points().size(), t.target->sampling_distance(),
                    t.target->noise().sigma_d);
      });

  m.def("_register", &Register, py::arg("source"), py::arg("target"), py::arg("method"),
        py::arg("init"), py::arg("callback"), py::arg("threads"), py::arg("params"));

  m.def(
      "_evaluate",
      [](py::object source, py::object estimate, py::object truth, double d, double threshold) {
        const PointCloud cloud = CloudFromPython(source, "source");
        return PoseErrorToPython(EvaluatePose(cloud.points, TransformFromPython(estimate, "result"),
                                              TransformFromPython(truth, "gt"), d, threshold));
      },
      py::arg("source"), py::arg("estimate"), py::arg("truth"), py::arg("sampling_distance"),
      py::arg("success_threshold_d"));

  m.def("methods", [] {
    py::list names;
    for (const MethodSpec& spec : MethodTable()) names.append(std::string(spec.name));
    return names;
  });
  m.def("parameters", [] {
    const RegistrationOptions defaults;
    py::list rows;
    for (const ParameterSpec& spec : ParameterTable()) {
      // "must be in [1, 100000]" -> "[1, 100000]": the values it takes.
      std::string range = spec.Rule();
      for (std::string_view prefix : {"must be ", "in "}) {
        if (range.starts_with(prefix)) range.erase(0, prefix.size());
      }
      std::string keyword(spec.flag);
      std::replace(keyword.begin(), keyword.end(), '-', '_');
      rows.append(py::dict(
          py::arg("name") = std::string(spec.wire_field), py::arg("path") = std::string(spec.name),
          py::arg("flag") = "--" + std::string(spec.flag), py::arg("alias") = keyword,
          py::arg("default") = spec.Format(spec.get(defaults)), py::arg("range") = range,
          py::arg("rule") = spec.Rule(), py::arg("help") = std::string(spec.help)));
    }
    return rows;
  });
}

py::dict AlignEdgeToPython(const AlignEdge& e) {
  return py::dict(py::arg("from") = e.from, py::arg("to") = e.to,
                  py::arg("relative") = Matrix4(e.relative),
                  py::arg("termination") = std::string(TerminationName(e.registration.termination)),
                  py::arg("iterations") = e.registration.iterations, py::arg("overlap") = e.overlap,
                  py::arg("correspondences") = e.correspondences,
                  py::arg("residual_before_d") = e.residual_before_d,
                  py::arg("residual_after_d") = e.residual_after_d, py::arg("trusted") = e.trusted,
                  py::arg("kept") = e.kept,
                  py::arg("verdict") = std::string(VerdictName(e.verification.verdict)));
}

AlignOptions AlignOptionsFromPython(py::object poses, const std::string& pairs,
                                    const std::string& method, double min_overlap,
                                    py::handle overlap_distance, int anchor, int threads,
                                    const py::dict& params) {
  CheckThreads(threads);
  AlignOptions options;
  options.edge = OptionsFromPython(method, params);
  options.pairs = ValueOrThrow(ParseEnum<PairPolicy>(PairPolicyNames(), pairs, "pairs"));
  options.min_overlap = min_overlap;
  options.overlap_distance = LengthFromPython(overlap_distance, "overlap_distance_d");
  options.anchor = anchor;
  options.threads = threads;
  if (!poses.is_none()) {
    std::size_t i = 0;
    for (py::handle pose : poses) {
      options.initial_poses.push_back(TransformFromPython(pose, absl::StrCat("poses[", i++, "]")));
    }
  }
  return options;
}

py::dict AlignResultToPython(const AlignResult& r) {
  py::list out_poses, chained, edges;
  for (const Matrix4& p : r.poses) out_poses.append(Matrix4(p));
  for (const Matrix4& p : r.chained_poses) chained.append(Matrix4(p));
  for (const AlignEdge& e : r.edges) edges.append(AlignEdgeToPython(e));
  py::list covariances;
  for (const std::optional<Matrix6>& c : r.pose_covariances) {
    covariances.append(c ? py::cast(Matrix6(*c)) : py::none());
  }
  return py::dict(py::arg("poses") = out_poses, py::arg("chained_poses") = chained,
                  py::arg("pose_covariances") = covariances, py::arg("edges") = edges,
                  py::arg("chain_deviation_d") = r.chain_deviation_d,
                  py::arg("loop_closure_rotation_deg") = r.loop_closure_rotation_deg,
                  py::arg("loop_closure_error_d") = r.loop_closure_error_d,
                  py::arg("loop_closure_exceeded") = r.loop_closure_exceeded,
                  py::arg("unverified_scans") = r.unverified_scans,
                  py::arg("sampling_distance") = r.sampling_distance,
                  py::arg("graph_iterations") = r.graph_iterations,
                  py::arg("covariance_weighted_edges") = r.covariance_weighted_edges,
                  py::arg("seconds") = r.seconds);
}

// The callback of an alignment: (edge dict, done, total).
std::function<void(const AlignEdge&, int, int)> OnEdge(CallbackBridge& bridge) {
  return [&bridge](const AlignEdge& edge, int done, int total) {
    bridge.Invoke([&](const py::object& f) { return f(AlignEdgeToPython(edge), done, total); });
  };
}

py::dict AlignScansFromPython(const py::list& scans, py::object poses, const std::string& pairs,
                              const std::string& method, double min_overlap,
                              py::handle overlap_distance, int anchor, int threads,
                              py::object callback, const py::dict& params) {
  std::vector<PointCloud> clouds;
  for (std::size_t i = 0; i < scans.size(); ++i) {
    clouds.push_back(CloudFromPython(scans[i], absl::StrCat("scans[", i, "]")));
  }
  const AlignOptions options = AlignOptionsFromPython(poses, pairs, method, min_overlap,
                                                      overlap_distance, anchor, threads, params);
  CallbackBridge bridge(std::move(callback));
  AlignCallbacks callbacks;
  callbacks.should_stop = [&bridge] { return bridge.ShouldStop(); };
  callbacks.on_edge = OnEdge(bridge);
  absl::StatusOr<AlignResult> result;
  {
    py::gil_scoped_release release;
    result = AlignScans(clouds, options, callbacks);
  }
  bridge.RaiseIfFailed();
  return AlignResultToPython(ValueOrThrow(std::move(result)));
}

// The scans under their poses as one cloud; resampled onto the joint MLS surface when asked,
// with d the scans' mean sampling distance unless given.
py::dict MergeScansFromPython(const py::list& scans, const py::list& poses, bool resample,
                              py::handle spacing, py::handle radius, py::object d, int threads) {
  CheckThreads(threads);
  std::vector<PointCloud> clouds;
  std::vector<Matrix4> transforms;
  for (std::size_t i = 0; i < scans.size(); ++i) {
    clouds.push_back(CloudFromPython(scans[i], absl::StrCat("scans[", i, "]")));
  }
  std::size_t i = 0;
  for (py::handle pose : poses) {
    transforms.push_back(TransformFromPython(pose, absl::StrCat("poses[", i++, "]")));
  }
  if (transforms.size() != clouds.size()) {
    throw py::value_error(
        absl::StrCat("poses: ", transforms.size(), " poses for ", clouds.size(), " scans"));
  }
  PointCloud merged = MergeScans(clouds, transforms);
  if (!resample) return CloudToPython(merged);
  const std::optional<double> given_d =
      d.is_none() ? std::nullopt : std::optional<double>(d.cast<double>());
  SurfaceResampling options;
  options.spacing = LengthFromPython(spacing, "spacing_d");
  options.radius = LengthFromPython(radius, "radius_d");
  options.threads = threads;
  absl::StatusOr<ResampledCloud> resampled;
  {
    py::gil_scoped_release release;
    double unit = given_d.value_or(0.0);
    for (std::size_t k = 0; !given_d && k < clouds.size(); ++k) {
      const KdTree tree(clouds[k].points);
      unit += SamplingDistance(clouds[k].points, tree) / static_cast<double>(clouds.size());
    }
    resampled = ResampleOnMlsSurface(merged, unit, options);
  }
  return CloudToPython(ValueOrThrow(std::move(resampled)).cloud);
}

void BindMultiview(py::module_& m) {
  m.def("_merge_scans", &MergeScansFromPython, py::arg("scans"), py::arg("poses"),
        py::arg("resample"), py::arg("spacing_d"), py::arg("radius_d"), py::arg("d"),
        py::arg("threads"));
  m.def("_align_scans", &AlignScansFromPython, py::arg("scans"), py::arg("poses"), py::arg("pairs"),
        py::arg("method"), py::arg("min_overlap"), py::arg("overlap_distance_d"), py::arg("anchor"),
        py::arg("threads"), py::arg("callback"), py::arg("params"));
  m.def(
      "read_poses",
      [](const std::string& path, const std::vector<std::string>& scan_paths) {
        py::list out;
        for (const Matrix4& p : ValueOrThrow(ReadPoses(path, scan_paths))) out.append(Matrix4(p));
        return out;
      },
      py::arg("path"), py::arg("scan_paths"),
      "Poses (scan -> common frame) from a .conf (Stanford bmesh lines, rotation R(q)^T) or a "
      "file of 16 row-major numbers per line, one 4x4 array per scan path.");
}

void BindClient(py::module_& m) {
  using client::Client;
  py::class_<Client>(m, "_Client")
      .def(py::init([](const std::string& address, const std::string& token, bool tls,
                       const std::string& ca_cert, const std::string& client_cert,
                       const std::string& client_key, double deadline_seconds, int max_attempts,
                       bool float32) {
             client::ClientOptions options;
             options.address = address;
             options.token = token;
             options.tls = tls;
             options.ca_cert = ca_cert;
             options.client_cert = client_cert;
             options.client_key = client_key;
             options.deadline_seconds = deadline_seconds;
             options.max_attempts = max_attempts;
             options.float32 = float32;
             py::gil_scoped_release release;
             return ValueOrThrow(Client::Connect(options));
           }),
           py::arg("address"), py::arg("token"), py::arg("tls"), py::arg("ca_cert"),
           py::arg("client_cert"), py::arg("client_key"), py::arg("deadline_seconds"),
           py::arg("max_attempts"), py::arg("float32"))
      .def("upload_target",
           [](Client& c, const std::string& id, py::object cloud) {
             auto shared = std::make_shared<const PointCloud>(CloudFromPython(cloud, "cloud"));
             py::gil_scoped_release release;
             TargetInfo info = ValueOrThrow(c.UploadTarget(id, shared));
             py::gil_scoped_acquire gil;
             return TargetInfoToPython(info);
           })
      .def("get_target",
           [](Client& c, const std::string& id) {
             absl::StatusOr<TargetInfo> info;
             {
               py::gil_scoped_release release;
               info = c.GetTarget(id);
             }
             return TargetInfoToPython(ValueOrThrow(std::move(info)));
           })
      .def("list_targets",
           [](Client& c) {
             absl::StatusOr<std::vector<TargetInfo>> infos;
             {
               py::gil_scoped_release release;
               infos = c.ListTargets();
             }
             py::list out;
             for (const TargetInfo& info : ValueOrThrow(std::move(infos))) {
               out.append(TargetInfoToPython(info));
             }
             return out;
           })
      .def("delete_target",
           [](Client& c, const std::string& id) {
             absl::Status s;
             {
               py::gil_scoped_release release;
               s = c.DeleteTarget(id);
             }
             ThrowIfError(s);
           })
      .def("health",
           [](Client& c, std::size_t replica) {
             absl::StatusOr<client::ServerHealth> h;
             {
               py::gil_scoped_release release;
               h = c.Health(replica);
             }
             return ValueOrThrow(std::move(h)).status;
           })
      .def("stats_json",
           [](Client& c, std::size_t replica) {
             absl::StatusOr<std::string> s;
             {
               py::gil_scoped_release release;
               s = c.StatsJson(replica);
             }
             return ValueOrThrow(std::move(s));
           })
      .def("replicas", &Client::replicas)
      .def("replica_for", &Client::ReplicaFor)
      .def("register",
           [](Client& c, const std::string& target_id, py::object source, const std::string& method,
              py::object init, py::object gt, py::object callback, const py::dict& params) {
             const RegistrationOptions options = OptionsFromPython(method, params);
             const Matrix4 initial = TransformFromPython(init, "init");
             std::optional<Matrix4> truth;
             if (!gt.is_none()) truth = TransformFromPython(gt, "gt");
             const PointCloud cloud = CloudFromPython(source, "source");
             CallbackBridge bridge(std::move(callback));
             absl::StatusOr<client::RemoteRegistrationResult> remote;
             {
               py::gil_scoped_release release;
               remote = c.Register(
                   target_id, cloud, initial, options, truth,
                   [&bridge](const IterationReport& r) { bridge.OnIteration(r); },
                   bridge.stop_flag());
             }
             bridge.RaiseIfFailed();
             client::RemoteRegistrationResult r = ValueOrThrow(std::move(remote));
             py::dict out = ResultToPython(r.result);
             out["request_id"] = r.request_id;
             out["queue_seconds"] = r.queue_seconds;
             out["attempts"] = r.attempts;
             out["ground_truth_error"] = r.ground_truth_error
                                             ? py::object(PoseErrorToPython(*r.ground_truth_error))
                                             : py::none();
             return out;
           })
      .def("align_scans",
           [](Client& c, const py::list& scans, py::object poses, const std::string& pairs,
              const std::string& method, double min_overlap, py::handle overlap_distance,
              int anchor, py::object callback, const py::dict& params) {
             // A str is the id of a target on the server; anything else a cloud sent with the call.
             std::vector<client::RemoteScan> remote;
             for (std::size_t i = 0; i < scans.size(); ++i) {
               client::RemoteScan scan;
               if (py::isinstance<py::str>(scans[i])) {
                 scan.target_id = scans[i].cast<std::string>();
               } else {
                 scan.cloud = std::make_shared<const PointCloud>(
                     CloudFromPython(scans[i], absl::StrCat("scans[", i, "]")));
               }
               remote.push_back(std::move(scan));
             }
             const AlignOptions options = AlignOptionsFromPython(
                 poses, pairs, method, min_overlap, overlap_distance, anchor, 1, params);
             CallbackBridge bridge(std::move(callback));
             absl::StatusOr<client::RemoteAlignResult> aligned;
             {
               py::gil_scoped_release release;
               aligned = c.AlignScans(remote, options, OnEdge(bridge), bridge.stop_flag());
             }
             bridge.RaiseIfFailed();
             client::RemoteAlignResult r = ValueOrThrow(std::move(aligned));
             py::dict out = AlignResultToPython(r.result);
             out["request_id"] = r.request_id;
             out["queue_seconds"] = r.queue_seconds;
             return out;
           });
}

}  // namespace
}  // namespace mlsreg::python

PYBIND11_MODULE(_mlsreg, m) {
  using namespace mlsreg::python;
  m.doc() = "mlsreg's C++ core; use the mlsreg package.";
  static py::exception<StatusError> error(m, "Error", PyExc_RuntimeError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const StatusError& e) {
      const std::string message(e.status().message());
      switch (e.status().code()) {
        case absl::StatusCode::kInvalidArgument:
        case absl::StatusCode::kOutOfRange:
        case absl::StatusCode::kFailedPrecondition:
          PyErr_SetString(PyExc_ValueError, message.c_str());
          return;
        case absl::StatusCode::kNotFound:
          PyErr_SetString(PyExc_LookupError, message.c_str());
          return;
        default: {
          py::object instance = py::reinterpret_borrow<py::object>(error)(message);
          instance.attr("code") = absl::StatusCodeToString(e.status().code());
          PyErr_SetObject(error.ptr(), instance.ptr());
          return;
        }
      }
    }
  });
  BindLocal(m);
  BindMultiview(m);
  BindClient(m);
}
