#include "mlsreg/wire/options_codec.h"

#include <string>

#include "absl/strings/str_cat.h"
#include "google/protobuf/descriptor.h"
#include "google/protobuf/reflection.h"
#include "mlsreg/registration/parameters.h"
#include "mlsreg/wire/enum_codec.h"

namespace mlsreg::wire {
namespace {

using google::protobuf::FieldDescriptor;

const FieldDescriptor* WireField(const ParameterSpec& spec) {
  return v1::RegistrationParameters::descriptor()->FindFieldByName(std::string(spec.wire_field));
}

// The value of a set wire field in the row's value type; nullopt when unset (an enum: 0).
absl::StatusOr<std::optional<ParameterValue>> ReadField(const ParameterSpec& spec,
                                                        const v1::RegistrationParameters& p,
                                                        const FieldDescriptor& f,
                                                        std::string_view field) {
  const google::protobuf::Reflection& r = *p.GetReflection();
  if (spec.type == ParameterType::kEnum) {
    const int wire = r.GetEnumValue(p, &f);
    if (wire == 0) return std::nullopt;
    absl::StatusOr<int> value = EnumFromWire(*spec.enum_names, wire, 0, field);
    if (!value.ok()) return value.status();
    return ParameterValue(static_cast<std::int64_t>(*value));
  }
  if (!r.HasField(p, &f)) return std::nullopt;
  switch (f.cpp_type()) {
    case FieldDescriptor::CPPTYPE_INT32:
      return ParameterValue(static_cast<std::int64_t>(r.GetInt32(p, &f)));
    case FieldDescriptor::CPPTYPE_UINT64:
      return ParameterValue(r.GetUInt64(p, &f));
    case FieldDescriptor::CPPTYPE_DOUBLE:
      return ParameterValue(r.GetDouble(p, &f));
    case FieldDescriptor::CPPTYPE_BOOL:
      return ParameterValue(r.GetBool(p, &f));
    default:
      return absl::InternalError(std::string(field) + ": unsupported wire type");
  }
}

void WriteField(const ParameterSpec& spec, const ParameterValue& value, const FieldDescriptor& f,
                v1::RegistrationParameters* p) {
  const google::protobuf::Reflection& r = *p->GetReflection();
  if (std::holds_alternative<std::monostate>(value)) {  // auto: unset
    r.ClearField(p, &f);
    return;
  }
  if (spec.type == ParameterType::kEnum) {
    r.SetEnumValue(p, &f,
                   EnumToWire(*spec.enum_names, static_cast<int>(std::get<std::int64_t>(value))));
    return;
  }
  switch (f.cpp_type()) {
    case FieldDescriptor::CPPTYPE_INT32:
      r.SetInt32(p, &f, static_cast<std::int32_t>(std::get<std::int64_t>(value)));
      break;
    case FieldDescriptor::CPPTYPE_UINT64:
      r.SetUInt64(p, &f, std::get<std::uint64_t>(value));
      break;
    case FieldDescriptor::CPPTYPE_DOUBLE:
      r.SetDouble(p, &f, std::get<double>(value));
      break;
    case FieldDescriptor::CPPTYPE_BOOL:
      r.SetBool(p, &f, std::get<bool>(value));
      break;
    default:
      break;
  }
}

}  // namespace

std::string_view MethodName(v1::Method method) {
  auto m = MethodFromProto(method);
  return m.ok() ? mlsreg::MethodName(*m) : "";
}

absl::StatusOr<Method> MethodFromProto(v1::Method method) {
  return EnumFromWire(MethodNames(), method, RegistrationOptions().method, "method");
}

v1::Method MethodToProto(Method method) {
  return static_cast<v1::Method>(EnumToWire(MethodNames(), static_cast<int>(method)));
}

absl::StatusOr<RegistrationOptions> OptionsFromProto(v1::Method method,
                                                     const v1::RegistrationParameters& p) {
  RegistrationOptions o;
  auto m = MethodFromProto(method);
  if (!m.ok()) return m.status();
  o.method = *m;
  for (const ParameterSpec& spec : ParameterTable()) {
    const std::string field = "parameters." + std::string(spec.wire_field);
    const FieldDescriptor* f = WireField(spec);
    if (f == nullptr) return absl::InternalError(absl::StrCat(field, ": not in the proto"));
    absl::StatusOr<std::optional<ParameterValue>> value = ReadField(spec, p, *f, field);
    if (!value.ok()) return value.status();
    if (!value->has_value()) continue;
    if (absl::Status s = spec.Check(**value, field); !s.ok()) return s;
    spec.set(o, **value);
  }
  for (const auto& [wire_field, metres] : p.absolute_lengths()) {
    const ParameterSpec* spec = nullptr;
    for (const ParameterSpec& row : ParameterTable()) {
      if (row.wire_field == wire_field && row.IsLength()) spec = &row;
    }
    if (spec == nullptr) {
      return absl::InvalidArgumentError(absl::StrCat("parameters.absolute_lengths: '", wire_field,
                                                     "' is not a length parameter"));
    }
    o.absolute_lengths.insert_or_assign(std::string(spec->name), metres);
  }
  if (absl::Status s = ValidateOptions(o); !s.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("parameters.", s.message()));
  }
  return o;
}

void OptionsToProto(const RegistrationOptions& o, v1::Method* method,
                    v1::RegistrationParameters* p) {
  *method = MethodToProto(o.method);
  p->Clear();
  for (const ParameterSpec& spec : ParameterTable()) {
    if (const FieldDescriptor* f = WireField(spec)) WriteField(spec, spec.get(o), *f, p);
  }
  for (const auto& [name, metres] : o.absolute_lengths) {
    if (const ParameterSpec* spec = FindParameter(name)) {
      (*p->mutable_absolute_lengths())[std::string(spec->wire_field)] = metres;
    }
  }
}

}  // namespace mlsreg::wire
