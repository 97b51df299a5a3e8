#include "mlsreg/core/cloud_digest.h"

#include <openssl/evp.h>

#include <bit>
#include <cstdint>
#include <cstring>
#include <memory>

namespace mlsreg {
namespace {

// Feeds values in their canonical little-endian form, buffered so that hashing 20 M points is a
// few large EVP_DigestUpdate calls.
class CanonicalHasher {
 public:
  CanonicalHasher() : context_(EVP_MD_CTX_new(), EVP_MD_CTX_free) {
    EVP_DigestInit_ex(context_.get(), EVP_sha256(), nullptr);
  }
  void Bytes(const void* data, std::size_t size) {
    if (used_ + size > sizeof buffer_) Flush();
    if (size > sizeof buffer_) {
      EVP_DigestUpdate(context_.get(), data, size);
      return;
    }
    std::memcpy(buffer_ + used_, data, size);
    used_ += size;
  }
  void U64(std::uint64_t v) {
    if constexpr (std::endian::native == std::endian::big) v = __builtin_bswap64(v);
    Bytes(&v, sizeof v);
  }
  void F64(double v) { U64(std::bit_cast<std::uint64_t>(v)); }
  void Vec(const Vec3& v) {
    F64(v.x());
    F64(v.y());
    F64(v.z());
  }
  std::string HexDigest() {
    Flush();
    unsigned char digest[EVP_MAX_MD_SIZE];
    unsigned int length = 0;
    EVP_DigestFinal_ex(context_.get(), digest, &length);
    static constexpr char kHex[] = "0123456789abcdef";
    std::string out = "sha256:";
    for (unsigned int i = 0; i < length; ++i) {
      out.push_back(kHex[digest[i] >> 4]);
      out.push_back(kHex[digest[i] & 15]);
    }
    return out;
  }

 private:
  void Flush() {
    if (used_ > 0) EVP_DigestUpdate(context_.get(), buffer_, used_);
    used_ = 0;
  }
  std::unique_ptr<EVP_MD_CTX, void (*)(EVP_MD_CTX*)> context_;
  unsigned char buffer_[1 << 16];
  std::size_t used_ = 0;
};

}  // namespace

std::string CloudDigest(const PointCloud& cloud) {
  CanonicalHasher h;
  static constexpr char kVersion[] = "mlsreg-cloud-v1";
  h.Bytes(kVersion, sizeof kVersion - 1);
  h.U64(cloud.points.size());
  h.U64(cloud.normals.size());
  for (const Vec3& p : cloud.points) h.Vec(p);
  for (const Vec3& n : cloud.normals) h.Vec(n);
  h.U64(cloud.viewpoint ? 1 : 0);
  if (cloud.viewpoint) h.Vec(*cloud.viewpoint);
  h.U64(cloud.intrinsics ? 1 : 0);
  if (cloud.intrinsics) {
    const PinholeIntrinsics& k = *cloud.intrinsics;
    h.U64(static_cast<std::uint64_t>(k.width));
    h.U64(static_cast<std::uint64_t>(k.height));
    for (double v : {k.fx, k.fy, k.cx, k.cy}) h.F64(v);
  }
  return h.HexDigest();
}

}  // namespace mlsreg
