// NumPy arrays <-> PointCloud. A cloud comes from Python as
//  - an array of shape (N, 3) (points) or (N, 6) (points and normals), float64 or float32;
//  - or any object with `points` (and optionally `normals`, `colors`, `intrinsics`, `viewpoint`)
//    attributes: mlsreg.Cloud, or an open3d.geometry.PointCloud;
//  - or an open3d.t.geometry.PointCloud (its `point` map: positions, normals, colors).
// Colours are uint8 (0-255) or integer arrays, or float arrays in [0, 1] (Open3D's).
// Anything else (another dtype, another shape) is a ValueError naming the field; the library then
// validates the cloud (finite coordinates, unit normals, enough points) with its own messages.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <string>

#include "mlsreg/core/point_cloud.h"

namespace mlsreg::python {

namespace py = pybind11;

// Requires the GIL. `field` names the argument in messages ("source", "target").
PointCloud CloudFromPython(py::handle object, std::string_view field);
// Points (and normals when given) from separate arrays; `normals` may be None.
PointCloud CloudFromArrays(py::handle points, py::handle normals, std::string_view field);
// {"width", "height", "fx", "fy", "cx", "cy"}, as a dict or an object with those attributes.
PinholeIntrinsics IntrinsicsFromPython(py::handle object, std::string_view field);

// An (N, 3) float64 array (a copy).
py::array_t<double> ToArray(const std::vector<Vec3>& vectors);
// {"points": (N,3), "normals": (N,3) or None, "colors": (N,3) uint8 or None, "viewpoint": (3,)
// or None, "intrinsics": dict or None}.
py::dict CloudToPython(const PointCloud& cloud);

}  // namespace mlsreg::python
