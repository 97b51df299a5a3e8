// The fuzz targets: every parser of untrusted bytes, each with the properties its output must
// have (a violated property is a crash, like a sanitizer report). One libFuzzer binary per
// target is built from fuzz_main.cc with MLSREG_FUZZ_TARGET naming its function here.
#pragma once

#include <cstdint>
#include <string_view>

namespace mlsreg::fuzz {

// Point-cloud readers: a parsed cloud is valid, and survives a write and read bit for bit.
void PlyReader(std::string_view bytes);
void PcdReader(std::string_view bytes);
void XyzReader(std::string_view bytes);
void NpyReader(std::string_view bytes);
// Mesh readers: a parsed mesh is valid (indices in range, finite vertices).
void OffReader(std::string_view bytes);
void ObjReader(std::string_view bytes);
// The .intrinsics sidecar: parsed intrinsics are valid.
void IntrinsicsReader(std::string_view bytes);
// The wire: length-prefixed CreateTargetRequest messages (header, then chunks) through the
// server's checks and decoder; a decoded cloud is valid and has the declared size.
void WireCloud(std::string_view bytes);
// The wire: a RegisterHeader; parameters that convert pass ValidateOptions and convert back to
// the same options.
void WireParameters(std::string_view bytes);

// Once per process: silences protobuf's log of malformed strings (expected, and noisy).
void Initialize();

// Length-prefixed framing of WireCloud's input: 4 bytes little-endian length, then the message.
void AppendFrame(std::string_view message, std::string* out);

}  // namespace mlsreg::fuzz
