// TargetInfo: what a catalogue of prepared targets (the server's cache) says about one of them.
// The server fills it, the wire carries it (proto/wire/targets_codec.h), the client returns it.
#pragma once

#include <cstdint>
#include <string>

#include "mlsreg/core/enum_names.h"

namespace mlsreg {

enum class TargetState {
  kReady,   // built and resident in memory
  kStored,  // persisted; rebuilt on first use
};
const EnumNames& TargetStateNames();  // "ready", "stored"; wire enum "TargetState"

struct TargetInfo {
  std::string id;
  TargetState state = TargetState::kReady;
  std::uint64_t point_count = 0;
  std::uint64_t memory_bytes = 0;  // resident bytes, or the last known value when stored
  double sampling_distance = 0.0;  // d
  double build_seconds = 0.0;      // kd-tree, normals, curvature (and depth grid)
  std::uint64_t registrations = 0;
  double noise_sigma_d = 0.0;   // the cloud's estimated noise (units of d, EstimateNoise)
  bool has_intrinsics = false;  // organised scan: reverse calibration can use it
  std::string digest;           // "sha256:..." of its content (mlsreg/core/cloud_digest.h)
};

}  // namespace mlsreg
