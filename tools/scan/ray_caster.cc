#include "scan/ray_caster.h"

#include <embree3/rtcore.h>

#include <Eigen/Geometry>
#include <cmath>
#include <limits>

#include "absl/strings/str_cat.h"

namespace mlsreg::scan {

struct RayCaster::Embree {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  ~Embree() {
    if (scene != nullptr) rtcReleaseScene(scene);
    if (device != nullptr) rtcReleaseDevice(device);
  }
};

RayCaster::RayCaster(const TriangleMesh& mesh) : mesh_(mesh), embree_(std::make_unique<Embree>()) {}
RayCaster::~RayCaster() = default;

absl::StatusOr<std::unique_ptr<RayCaster>> RayCaster::Build(const TriangleMesh& mesh) {
  if (absl::Status s = ValidateTriangleMesh(mesh); !s.ok()) return s;
  std::unique_ptr<RayCaster> caster(new RayCaster(mesh));
  Embree& e = *caster->embree_;
  e.device = rtcNewDevice("threads=1");
  if (e.device == nullptr) return absl::InternalError("Embree: cannot create a device");
  e.scene = rtcNewScene(e.device);
  rtcSetSceneBuildQuality(e.scene, RTC_BUILD_QUALITY_HIGH);
  RTCGeometry geometry = rtcNewGeometry(e.device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0,
                                                               RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                                               mesh.vertices.size()));
  auto* indices = static_cast<std::uint32_t*>(
      rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                              3 * sizeof(std::uint32_t), mesh.triangles.size()));
  if (vertices == nullptr || indices == nullptr) {
    rtcReleaseGeometry(geometry);
    return absl::ResourceExhaustedError("Embree: cannot allocate the mesh buffers");
  }
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    for (int k = 0; k < 3; ++k) vertices[3 * i + k] = static_cast<float>(mesh.vertices[i][k]);
  }
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) indices[3 * t + k] = mesh.triangles[t][k];
  }
  rtcCommitGeometry(geometry);
  rtcAttachGeometry(e.scene, geometry);
  rtcReleaseGeometry(geometry);
  rtcCommitScene(e.scene);
  if (rtcGetDeviceError(e.device) != RTC_ERROR_NONE) {
    return absl::InternalError("Embree: building the scene failed");
  }
  return caster;
}

std::optional<RayHit> RayCaster::Cast(const Vec3& origin, const Vec3& direction) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit query{};
  query.ray.org_x = static_cast<float>(origin.x());
  query.ray.org_y = static_cast<float>(origin.y());
  query.ray.org_z = static_cast<float>(origin.z());
  query.ray.dir_x = static_cast<float>(direction.x());
  query.ray.dir_y = static_cast<float>(direction.y());
  query.ray.dir_z = static_cast<float>(direction.z());
  query.ray.tnear = 0.0f;
  query.ray.tfar = std::numeric_limits<float>::infinity();
  query.ray.mask = 0xFFFFFFFFu;  // Debian builds Embree with ray masks: a zero mask hits nothing
  query.ray.flags = 0;
  query.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  query.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(embree_->scene, &context, &query);
  if (query.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;

  RayHit hit;
  hit.triangle = query.hit.primID;
  const auto& t = mesh_.triangles[hit.triangle];
  const Vec3 &a = mesh_.vertices[t[0]], &b = mesh_.vertices[t[1]], &c = mesh_.vertices[t[2]];
  Vec3 normal = (b - a).cross(c - a);
  const double length = normal.norm();
  hit.distance = query.ray.tfar;
  if (length > 0.0) {
    normal /= length;
    const double along = normal.dot(direction);
    // Refine the float distance against the triangle's plane, in double precision.
    if (std::abs(along) > 1e-6) {
      const double refined = normal.dot(a - origin) / along;
      if (std::abs(refined - hit.distance) < 1e-3 * hit.distance) hit.distance = refined;
    }
    hit.normal = along > 0.0 ? Vec3(-normal) : normal;
  } else {
    hit.normal = -direction;
  }
  return hit;
}

}  // namespace mlsreg::scan
