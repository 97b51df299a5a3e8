#include "mlsreg/wire/transform_codec.h"

#include "absl/strings/str_cat.h"

namespace mlsreg::wire {

void ToProto(const Matrix4& m, v1::Transform* out) {
  out->clear_row_major();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) out->add_row_major(m(r, c));
  }
}

absl::StatusOr<Matrix4> FromProto(const v1::Transform& t, std::string_view field) {
  const std::string f(field);
  if (t.row_major_size() != 16) {
    return absl::InvalidArgumentError(
        absl::StrCat(f, ": needs 16 row-major numbers, got ", t.row_major_size()));
  }
  Matrix4 m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = t.row_major(4 * r + c);
  }
  if (absl::Status s = CheckRigid(m, f); !s.ok()) return s;
  return m;
}

Matrix4 ReportedFromProto(const v1::Transform& t) {
  Matrix4 m = Matrix4::Identity();
  if (t.row_major_size() == 16) {
    for (int i = 0; i < 16; ++i) m(i / 4, i % 4) = t.row_major(i);
  }
  return m;
}

}  // namespace mlsreg::wire
