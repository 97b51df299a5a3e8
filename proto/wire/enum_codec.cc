#include "mlsreg/wire/enum_codec.h"

#include <string>

#include "absl/strings/str_cat.h"
#include "google/protobuf/descriptor.h"
#include "mlsreg/v1/mlsreg.pb.h"

namespace mlsreg::wire {
namespace {

const google::protobuf::EnumDescriptor* WireEnum(const EnumNames& names) {
  // Linking mlsreg.pb.cc registers the descriptors in the generated pool; touching one of its
  // enums keeps the linker from dropping it.
  (void)v1::Method_descriptor();
  return google::protobuf::DescriptorPool::generated_pool()->FindEnumTypeByName(
      "mlsreg.v1." + std::string(names.wire_enum));
}

}  // namespace

int EnumToWire(const EnumNames& names, int value) {
  const google::protobuf::EnumDescriptor* e = WireEnum(names);
  if (e == nullptr) return 0;
  for (const EnumValueName& v : names.values) {
    if (v.value != value) continue;
    const auto* wire =
        e->FindValueByName(std::string(names.wire_prefix) + std::string(v.wire_suffix));
    return wire != nullptr ? wire->number() : 0;
  }
  return 0;
}

absl::StatusOr<int> EnumFromWire(const EnumNames& names, int wire_value, int unspecified,
                                 std::string_view field) {
  const auto unknown = [&] {
    return absl::InvalidArgumentError(
        absl::StrCat(std::string(field), ": unknown value ", wire_value));
  };
  if (wire_value == 0) return unspecified;
  const google::protobuf::EnumDescriptor* e = WireEnum(names);
  const auto* wire = e != nullptr ? e->FindValueByNumber(wire_value) : nullptr;
  if (wire == nullptr) return unknown();
  std::string_view suffix = wire->name();
  if (!suffix.starts_with(names.wire_prefix)) return unknown();
  suffix.remove_prefix(names.wire_prefix.size());
  for (const EnumValueName& v : names.values) {
    if (v.wire_suffix == suffix) return v.value;
  }
  return unknown();
}

}  // namespace mlsreg::wire
