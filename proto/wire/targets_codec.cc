#include "mlsreg/wire/targets_codec.h"

#include "mlsreg/wire/enum_codec.h"

namespace mlsreg::wire {

void ToProto(const TargetInfo& info, v1::Target* out) {
  out->set_target_id(info.id);
  out->set_state(
      static_cast<v1::TargetState>(EnumToWire(TargetStateNames(), static_cast<int>(info.state))));
  out->set_point_count(info.point_count);
  out->set_memory_bytes(info.memory_bytes);
  out->set_sampling_distance(info.sampling_distance);
  out->set_build_seconds(info.build_seconds);
  out->set_registrations(info.registrations);
  out->set_has_intrinsics(info.has_intrinsics);
  out->set_noise_sigma_d(info.noise_sigma_d);
  out->set_content_digest(info.digest);
}

TargetInfo FromProto(const v1::Target& t) {
  TargetInfo info;
  info.id = t.target_id();
  info.state = EnumFromWire(TargetStateNames(), t.state(), TargetState::kReady, "state")
                   .value_or(TargetState::kReady);
  info.point_count = t.point_count();
  info.memory_bytes = t.memory_bytes();
  info.sampling_distance = t.sampling_distance();
  info.build_seconds = t.build_seconds();
  info.registrations = t.registrations();
  info.has_intrinsics = t.has_intrinsics();
  info.noise_sigma_d = t.noise_sigma_d();
  info.digest = t.content_digest();
  return info;
}

}  // namespace mlsreg::wire
