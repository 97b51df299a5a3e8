#include "python/src/cloud_arrays.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "python/src/status_errors.h"

namespace mlsreg::python {
namespace {

std::string Field(std::string_view field) { return std::string(field); }

[[noreturn]] void Invalid(const std::string& message) {
  throw StatusError(absl::InvalidArgumentError(message));
}

// The object as a C-contiguous float64 array of shape (N, columns) with columns in `allowed`.
py::array_t<double, py::array::c_style> AsCoordinateArray(py::handle object,
                                                          std::initializer_list<int> allowed,
                                                          const std::string& field) {
  py::array array = py::module_::import("numpy").attr("asarray")(object);
  const char kind = array.dtype().kind();
  if (kind != 'f') {
    Invalid(absl::StrCat(Field(field), ": dtype ", std::string(py::str(array.dtype())),
                         " is not a floating-point type; pass float64 (or float32) coordinates"));
  }
  std::string shapes;
  bool shape_ok = array.ndim() == 2;
  for (int columns : allowed) {
    shapes += shapes.empty() ? absl::StrCat("(N, ", columns, ")")
                             : absl::StrCat(" or (N, ", columns, ")");
  }
  if (shape_ok) {
    shape_ok = false;
    for (int columns : allowed) shape_ok |= array.shape(1) == columns;
  }
  if (!shape_ok) {
    std::string shape = "(";
    for (py::ssize_t i = 0; i < array.ndim(); ++i) {
      shape += absl::StrCat(i ? ", " : "", array.shape(i));
    }
    Invalid(absl::StrCat(Field(field), ": shape ", shape, array.ndim() == 1 ? ",)" : ")",
                         " is not ", shapes));
  }
  return py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(array);
}

std::vector<Vec3> Rows(const py::array_t<double, py::array::c_style>& array, int first_column) {
  const auto view = array.unchecked<2>();
  std::vector<Vec3> rows(static_cast<std::size_t>(view.shape(0)));
  for (py::ssize_t i = 0; i < view.shape(0); ++i) {
    rows[i] = Vec3(view(i, first_column), view(i, first_column + 1), view(i, first_column + 2));
  }
  return rows;
}

bool IsNone(py::handle h) { return !h || h.is_none(); }

// Colours of `n` points: integers 0-255, or floats in [0, 1] (Open3D); empty for an empty array.
std::vector<Rgb> ColorsFromPython(py::handle object, std::size_t n, const std::string& field) {
  py::array array = py::module_::import("numpy").attr("asarray")(object);
  if (array.size() == 0) return {};
  const char kind = array.dtype().kind();
  if (array.ndim() != 2 || array.shape(1) != 3 || static_cast<std::size_t>(array.shape(0)) != n) {
    Invalid(absl::StrCat(field, ": colours must be an (N, 3) array, one row per point"));
  }
  if (kind != 'u' && kind != 'i' && kind != 'f') {
    Invalid(absl::StrCat(field, ": dtype ", std::string(py::str(array.dtype())),
                         " is not a colour type; pass uint8 (0-255) or floats in [0, 1]"));
  }
  const bool unit_scale = kind == 'f';
  const auto values = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(array);
  const auto view = values.unchecked<2>();
  std::vector<Rgb> colors(n);
  for (std::size_t i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) {
      const double v = view(i, c);
      if (!(v >= 0.0 && v <= (unit_scale ? 1.0 : 255.0))) {
        Invalid(absl::StrCat(field, ": colour ", v, " of point ", i, " is not in ",
                             unit_scale ? "[0, 1]" : "[0, 255]"));
      }
      colors[i][c] = static_cast<std::uint8_t>(std::lround(unit_scale ? 255.0 * v : v));
    }
  }
  return colors;
}

// An attribute that may be a value or, as Open3D's has_normals(), absent or empty.
py::object OptionalAttribute(py::handle object, const char* name) {
  if (!py::hasattr(object, name)) return py::none();
  py::object value = object.attr(name);
  if (PyCallable_Check(value.ptr())) value = value();
  return value;
}

}  // namespace

PointCloud CloudFromArrays(py::handle points, py::handle normals, std::string_view field) {
  PointCloud cloud;
  const auto p = AsCoordinateArray(points, {3, 6}, Field(field));
  cloud.points = Rows(p, 0);
  if (p.shape(1) == 6) {
    if (!IsNone(normals)) {
      Invalid(absl::StrCat(Field(field), ": normals given twice (an (N, 6) array and normals=)"));
    }
    cloud.normals = Rows(p, 3);
  } else if (!IsNone(normals)) {
    const std::string normals_field = absl::StrCat(Field(field), ".normals");
    const auto n = AsCoordinateArray(normals, {3}, normals_field);
    if (n.shape(0) != 0) {
      if (n.shape(0) != p.shape(0)) {
        Invalid(
            absl::StrCat(normals_field, ": ", n.shape(0), " normals for ", p.shape(0), " points"));
      }
      cloud.normals = Rows(n, 0);
    }
  }
  return cloud;
}

PinholeIntrinsics IntrinsicsFromPython(py::handle object, std::string_view field) {
  PinholeIntrinsics k;
  const auto get = [&](const char* name) -> py::object {
    if (py::isinstance<py::dict>(object)) {
      py::dict d = py::reinterpret_borrow<py::dict>(object);
      if (!d.contains(name)) Invalid(absl::StrCat(Field(field), ": missing \"", name, "\""));
      return d[name];
    }
    if (!py::hasattr(object, name)) Invalid(absl::StrCat(Field(field), ": missing \"", name, "\""));
    return object.attr(name);
  };
  try {
    k.width = get("width").cast<int>();
    k.height = get("height").cast<int>();
    k.fx = get("fx").cast<double>();
    k.fy = get("fy").cast<double>();
    k.cx = get("cx").cast<double>();
    k.cy = get("cy").cast<double>();
  } catch (const py::cast_error&) {
    Invalid(
        absl::StrCat(Field(field), ": width and height must be integers, fx, fy, cx, cy numbers"));
  }
  ThrowIfError(ValidateIntrinsics(k, field));
  return k;
}

// An open3d.t.geometry.PointCloud: tensors in its `point` map, converted with .numpy().
PointCloud CloudFromTensorMap(py::handle object, std::string_view field) {
  py::object map = object.attr("point");
  const auto tensor = [&](const char* key) -> py::object {
    if (!map.attr("__contains__")(key).cast<bool>()) return py::none();
    return map.attr("__getitem__")(key).attr("numpy")();
  };
  py::object positions = tensor("positions");
  if (IsNone(positions)) Invalid(absl::StrCat(Field(field), ": the tensor cloud has no positions"));
  PointCloud cloud = CloudFromArrays(positions, tensor("normals"), field);
  if (py::object colors = tensor("colors"); !IsNone(colors)) {
    cloud.colors = ColorsFromPython(colors, cloud.size(), absl::StrCat(Field(field), ".colors"));
  }
  return cloud;
}

PointCloud CloudFromPython(py::handle object, std::string_view field) {
  if (IsNone(object))
    Invalid(absl::StrCat(Field(field), ": is None; pass an (N, 3) or (N, 6) array"));
  if (!py::isinstance<py::array>(object) && !py::hasattr(object, "points") &&
      py::hasattr(object, "point")) {
    return CloudFromTensorMap(object, field);
  }
  if (py::isinstance<py::array>(object) || !py::hasattr(object, "points")) {
    return CloudFromArrays(object, py::none(), field);
  }
  // mlsreg.Cloud or open3d.geometry.PointCloud.
  py::object normals = OptionalAttribute(object, "normals");
  if (py::hasattr(object, "has_normals") && !object.attr("has_normals")().cast<bool>()) {
    normals = py::none();
  }
  PointCloud cloud = CloudFromArrays(object.attr("points"), normals, field);
  py::object colors = OptionalAttribute(object, "colors");
  if (py::hasattr(object, "has_colors") && !object.attr("has_colors")().cast<bool>()) {
    colors = py::none();
  }
  if (!IsNone(colors)) {
    cloud.colors = ColorsFromPython(colors, cloud.size(), absl::StrCat(Field(field), ".colors"));
  }
  if (py::object k = OptionalAttribute(object, "intrinsics"); !IsNone(k)) {
    cloud.intrinsics = IntrinsicsFromPython(k, absl::StrCat(Field(field), ".intrinsics"));
  }
  if (py::object v = OptionalAttribute(object, "viewpoint"); !IsNone(v)) {
    py::array_t<double, py::array::c_style | py::array::forcecast> a =
        py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(v);
    if (!a || a.size() != 3) Invalid(absl::StrCat(Field(field), ".viewpoint: must be 3 numbers"));
    cloud.viewpoint = Vec3(a.data()[0], a.data()[1], a.data()[2]);
  }
  return cloud;
}

py::array_t<double> ToArray(const std::vector<Vec3>& vectors) {
  py::array_t<double> array({static_cast<py::ssize_t>(vectors.size()), py::ssize_t{3}});
  auto view = array.mutable_unchecked<2>();
  for (std::size_t i = 0; i < vectors.size(); ++i) {
    for (int c = 0; c < 3; ++c) view(i, c) = vectors[i][c];
  }
  return array;
}

py::dict CloudToPython(const PointCloud& cloud) {
  py::dict d;
  d["points"] = ToArray(cloud.points);
  d["normals"] = cloud.has_normals() ? py::object(ToArray(cloud.normals)) : py::none();
  if (cloud.has_colors()) {
    py::array_t<std::uint8_t> colors({static_cast<py::ssize_t>(cloud.size()), py::ssize_t{3}});
    auto view = colors.mutable_unchecked<2>();
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      for (int c = 0; c < 3; ++c) view(i, c) = cloud.colors[i][c];
    }
    d["colors"] = colors;
  } else {
    d["colors"] = py::none();
  }
  if (cloud.viewpoint) {
    d["viewpoint"] = ToArray({*cloud.viewpoint}).attr("reshape")(3);
  } else {
    d["viewpoint"] = py::none();
  }
  if (cloud.intrinsics) {
    const PinholeIntrinsics& k = *cloud.intrinsics;
    d["intrinsics"] =
        py::dict(py::arg("width") = k.width, py::arg("height") = k.height, py::arg("fx") = k.fx,
                 py::arg("fy") = k.fy, py::arg("cx") = k.cx, py::arg("cy") = k.cy);
  } else {
    d["intrinsics"] = py::none();
  }
  return d;
}

}  // namespace mlsreg::python
