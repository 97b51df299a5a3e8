// The parameter, method and enum tables against the proto descriptor: every registration
// parameter has exactly one wire field of a matching type and the wire has no field without a
// row; every enum row names a wire value and every wire value but UNSPECIFIED has a row; and
// options survive the wire unchanged.
#include <gtest/gtest.h>

#include <set>
#include <string>

#include "google/protobuf/descriptor.h"
#include "mlsreg/registration/parameters.h"
#include "mlsreg/wire/convert.h"

namespace mlsreg {
namespace {

using google::protobuf::EnumDescriptor;
using google::protobuf::FieldDescriptor;

FieldDescriptor::CppType WireTypeOf(ParameterType type) {
  switch (type) {
    case ParameterType::kInt:
      return FieldDescriptor::CPPTYPE_INT32;
    case ParameterType::kUint64:
      return FieldDescriptor::CPPTYPE_UINT64;
    case ParameterType::kDouble:
      return FieldDescriptor::CPPTYPE_DOUBLE;
    case ParameterType::kBool:
      return FieldDescriptor::CPPTYPE_BOOL;
    case ParameterType::kEnum:
      return FieldDescriptor::CPPTYPE_ENUM;
  }
  return FieldDescriptor::CPPTYPE_STRING;
}

// Every wire value but UNSPECIFIED has a row, and every row a wire value.
void ExpectEnumMatchesWire(const EnumNames& names) {
  SCOPED_TRACE(std::string(names.wire_enum));
  const EnumDescriptor* e = google::protobuf::DescriptorPool::generated_pool()->FindEnumTypeByName(
      "mlsreg.v1." + std::string(names.wire_enum));
  ASSERT_NE(e, nullptr);
  std::set<std::string> rows;
  for (const EnumValueName& v : names.values) {
    const std::string wire = std::string(names.wire_prefix) + std::string(v.wire_suffix);
    EXPECT_NE(e->FindValueByName(wire), nullptr) << wire << " is not in the proto";
    rows.insert(wire);
    EXPECT_EQ(wire::EnumFromWire(names, wire::EnumToWire(names, v.value), -1, "f").value(),
              v.value);
  }
  for (int i = 0; i < e->value_count(); ++i) {
    const std::string wire = e->value(i)->name();
    if (wire == std::string(names.wire_prefix) + "UNSPECIFIED") continue;
    EXPECT_TRUE(rows.count(wire)) << wire << " has no row in the library's table";
  }
}

TEST(ParameterTableTest, EveryParameterHasOneWireFieldOfItsTypeAndEveryFieldARow) {
  const auto* message = v1::RegistrationParameters::descriptor();
  std::set<std::string> names, flags, wire_fields;
  for (const ParameterSpec& spec : ParameterTable()) {
    SCOPED_TRACE(std::string(spec.name));
    EXPECT_TRUE(names.insert(std::string(spec.name)).second) << "name twice";
    EXPECT_TRUE(flags.insert(std::string(spec.flag)).second) << "flag twice";
    EXPECT_TRUE(wire_fields.insert(std::string(spec.wire_field)).second) << "wire field twice";
    EXPECT_FALSE(spec.help.empty());
    const FieldDescriptor* f = message->FindFieldByName(std::string(spec.wire_field));
    ASSERT_NE(f, nullptr) << spec.wire_field << " is not in RegistrationParameters";
    EXPECT_EQ(f->cpp_type(), WireTypeOf(spec.type));
    // Scalars are optional, so that unset means "the default"; enums have UNSPECIFIED for that.
    if (spec.type != ParameterType::kEnum) {
      EXPECT_TRUE(f->has_presence());
    }
    if (spec.type == ParameterType::kEnum) {
      ASSERT_NE(spec.enum_names, nullptr);
      EXPECT_EQ(f->enum_type()->name(), std::string(spec.enum_names->wire_enum));
    }
    // The default is inside the row's own range.
    EXPECT_TRUE(spec.Check(spec.get(RegistrationOptions()), spec.name).ok());
  }
  for (int i = 0; i < message->field_count(); ++i) {
    if (message->field(i)->name() == "absolute_lengths") continue;  // the lengths' other unit
    EXPECT_TRUE(wire_fields.count(message->field(i)->name()))
        << message->field(i)->name() << " has no row in the parameter table";
  }
}

TEST(ParameterTableTest, EnumTablesMatchTheWireEnums) {
  ExpectEnumMatchesWire(MethodNames());
  ExpectEnumMatchesWire(SicpMetricNames());
  ExpectEnumMatchesWire(FarQueryPolicyNames());
  ExpectEnumMatchesWire(MlsProjectionKindNames());
  ExpectEnumMatchesWire(CoarsePhaseFiltersNames());
  ExpectEnumMatchesWire(TerminationNames());
  ExpectEnumMatchesWire(StageNames());
  ExpectEnumMatchesWire(CandidateOriginNames());
  ExpectEnumMatchesWire(FinishKindNames());
  ExpectEnumMatchesWire(VerdictNames());
}

TEST(ParameterTableTest, MethodTableRowsAreCompleteAndNamesParse) {
  for (const MethodSpec& m : MethodTable()) {
    SCOPED_TRACE(std::string(m.name));
    EXPECT_EQ(ParseMethod(m.name).value(), m.method);
    EXPECT_NE(m.run, nullptr);
    EXPECT_TRUE(m.parameter_groups & kCommonParameters);
    // Sparse ICP methods have a correspondence policy; G-ICP and FGR bring their own matching.
    EXPECT_EQ(m.make_finder != nullptr, (m.parameter_groups & kSparseIcpParameters) != 0);
    EXPECT_EQ(wire::MethodFromProto(wire::MethodToProto(m.method)).value(), m.method);
  }
  EXPECT_EQ(wire::MethodFromProto(v1::METHOD_UNSPECIFIED).value(), Method::kAuto);
  EXPECT_FALSE(ParseMethod("icp").ok());
}

// Each parameter set to a value other than its default crosses the wire unchanged, and one
// outside its range (an enum number the enum does not have) is refused naming the wire field.
TEST(ParameterTableTest, EveryParameterCrossesTheWireAndOutOfRangeValuesNameTheWireField) {
  for (const ParameterSpec& spec : ParameterTable()) {
    SCOPED_TRACE(std::string(spec.name));
    RegistrationOptions options;
    const ParameterValue before = spec.get(options);
    ParameterValue changed = before;
    if (std::holds_alternative<std::monostate>(changed)) {  // auto: an explicit value
      changed = (spec.range.min + spec.range.max) / 2;
    } else if (auto* i = std::get_if<std::int64_t>(&changed)) {
      *i = spec.type == ParameterType::kEnum ? spec.enum_names->values.back().value
                                             : static_cast<std::int64_t>(spec.range.min) + 1;
      if (*i == std::get<std::int64_t>(before))
        *i = spec.enum_names ? spec.enum_names->values[0].value : *i + 1;
    } else if (auto* u = std::get_if<std::uint64_t>(&changed)) {
      *u += 12345;
    } else if (auto* d = std::get_if<double>(&changed)) {
      *d = std::isinf(spec.range.max) ? *d + 0.5 : (*d + spec.range.max) / 2;
    } else if (auto* b = std::get_if<bool>(&changed)) {
      *b = !*b;
    }
    ASSERT_NE(changed, before);
    ASSERT_TRUE(spec.Check(changed, spec.name).ok()) << spec.Format(changed);
    spec.set(options, changed);
    v1::Method method;
    v1::RegistrationParameters p;
    wire::OptionsToProto(options, &method, &p);
    auto back = wire::OptionsFromProto(method, p);
    ASSERT_TRUE(back.ok()) << back.status();
    EXPECT_EQ(spec.get(*back), changed);

    if (spec.type == ParameterType::kInt || spec.type == ParameterType::kDouble) {
      const auto* f = p.GetDescriptor()->FindFieldByName(std::string(spec.wire_field));
      if (f->cpp_type() == FieldDescriptor::CPPTYPE_INT32) {
        p.GetReflection()->SetInt32(&p, f, static_cast<int>(spec.range.min) - 1);
      } else {
        p.GetReflection()->SetDouble(&p, f, spec.range.min - 1.0);
      }
      auto refused = wire::OptionsFromProto(method, p);
      ASSERT_FALSE(refused.ok());
      EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument);
      EXPECT_NE(refused.status().message().find("parameters." + std::string(spec.wire_field)),
                std::string::npos)
          << refused.status();
    }
    if (spec.type == ParameterType::kEnum) {  // a number the enum does not have
      const auto* f = p.GetDescriptor()->FindFieldByName(std::string(spec.wire_field));
      p.GetReflection()->SetEnumValue(&p, f, 99);
      auto refused = wire::OptionsFromProto(method, p);
      ASSERT_FALSE(refused.ok());
      EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument);
      EXPECT_NE(refused.status().message().find("parameters." + std::string(spec.wire_field)),
                std::string::npos)
          << refused.status();
    }
  }
}

// The MLS radius defaults to auto, which travels as an unset field and comes back auto.
TEST(ParameterTableTest, AnAutomaticRadiusTravelsAsAnUnsetField) {
  RegistrationOptions options;
  EXPECT_FALSE(options.mls.radius_d.has_value());
  v1::Method method;
  v1::RegistrationParameters p;
  wire::OptionsToProto(options, &method, &p);
  EXPECT_FALSE(p.has_mls_radius_d());
  EXPECT_FALSE(wire::OptionsFromProto(method, p)->mls.radius_d.has_value());
  const ParameterSpec* radius = FindParameter("mls.radius_d");
  EXPECT_TRUE(
      std::holds_alternative<std::monostate>(radius->Parse("auto", "--mls-radius").value()));
  EXPECT_EQ(radius->Format(radius->get(options)), "auto");
  EXPECT_FALSE(FindParameter("convergence_d")->Parse("auto", "--convergence").ok());
}

TEST(ParameterTableTest, CliTextParsesToTheSameValuesAndBadTextNamesTheField) {
  const ParameterSpec* radius = FindParameter("mls.radius_d");
  ASSERT_NE(radius, nullptr);
  EXPECT_EQ(std::get<double>(radius->Parse("8", "--mls-radius").value()), 8.0);
  EXPECT_EQ(radius->Parse("-1", "--mls-radius").status().message(),
            "--mls-radius must be in (0, 100] or auto");
  EXPECT_NE(radius->Parse("eight", "--mls-radius").status().message().find("--mls-radius"),
            std::string::npos);
  const ParameterSpec* far = FindParameter("mls.far_queries");
  ASSERT_NE(far, nullptr);
  EXPECT_EQ(std::get<std::int64_t>(far->Parse("drop", "--mls-far-queries").value()),
            static_cast<int>(FarQueryPolicy::kDrop));
  EXPECT_NE(far->Parse("sometimes", "--mls-far-queries").status().message().find("known: "),
            std::string::npos);
}

// A length takes units of d ("5", "5d") or of the clouds ("1m", "30cm", "5mm"); other rows do
// not, and a bad length names its flag.
TEST(ParameterTableTest, LengthsTakeUnitsOfDOrMetres) {
  const ParameterSpec& max_distance = *FindParameter("filter.max_distance_d");
  const ParameterSpec& samples = *FindParameter("num_samples");
  EXPECT_TRUE(max_distance.IsLength());
  EXPECT_FALSE(samples.IsLength());
  RegistrationOptions o;
  ASSERT_TRUE(SetParameterFromText(o, max_distance, "30cm", "--max-distance").ok());
  EXPECT_DOUBLE_EQ(o.absolute_lengths.at("filter.max_distance_d"), 0.3);
  ASSERT_TRUE(SetParameterFromText(o, max_distance, "1.5 m", "--max-distance").ok());
  EXPECT_DOUBLE_EQ(o.absolute_lengths.at("filter.max_distance_d"), 1.5);
  ASSERT_TRUE(SetParameterFromText(o, *FindParameter("mls.radius_d"), "4mm", "--mls-radius").ok());
  EXPECT_DOUBLE_EQ(o.absolute_lengths.at("mls.radius_d"), 0.004);
  // A value in d replaces the one in metres.
  ASSERT_TRUE(SetParameterFromText(o, max_distance, "5d", "--max-distance").ok());
  EXPECT_EQ(o.absolute_lengths.count("filter.max_distance_d"), 0u);
  EXPECT_DOUBLE_EQ(o.filter.max_distance_d, 5.0);
  ASSERT_TRUE(SetParameterFromText(o, max_distance, "7", "--max-distance").ok());
  EXPECT_DOUBLE_EQ(o.filter.max_distance_d, 7.0);
  for (const char* bad : {"-1m", "m", "1 furlong", "1e999m", "nan m"}) {
    const absl::Status s = SetParameterFromText(o, max_distance, bad, "--max-distance");
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << bad;
    EXPECT_NE(s.message().find("--max-distance"), std::string::npos) << s;
  }
  EXPECT_FALSE(SetParameterFromText(o, samples, "3m", "--samples").ok());

  // Converted with the target's d; out of range after conversion names both units.
  auto resolved = ResolveLengths(o, 0.01);
  ASSERT_TRUE(resolved.ok()) << resolved.status();
  EXPECT_TRUE(resolved->absolute_lengths.empty());
  EXPECT_DOUBLE_EQ(*resolved->mls.radius_d, 0.4);
  EXPECT_DOUBLE_EQ(resolved->filter.max_distance_d, 7.0);
  o.absolute_lengths["mls.radius_d"] = 2.0;
  const absl::Status far = ResolveLengths(o, 0.01).status();
  EXPECT_NE(far.message().find("mls.radius_d = 2 m is 200 d on this target (d = 0.01 m)"),
            std::string::npos)
      << far;

  // Across the wire by field name; a field that is not a length is refused naming the map.
  RegistrationOptions sent;
  sent.absolute_lengths = {{"filter.max_distance_d", 0.25}, {"gicp.max_distance_d", 2.0}};
  v1::Method method;
  v1::RegistrationParameters p;
  wire::OptionsToProto(sent, &method, &p);
  EXPECT_DOUBLE_EQ(p.absolute_lengths().at("max_distance_d"), 0.25);
  auto back = wire::OptionsFromProto(method, p);
  ASSERT_TRUE(back.ok()) << back.status();
  EXPECT_EQ(back->absolute_lengths, sent.absolute_lengths);
  (*p.mutable_absolute_lengths())["num_samples"] = 1.0;
  EXPECT_NE(wire::OptionsFromProto(method, p).status().message().find(
                "parameters.absolute_lengths: 'num_samples' is not a length parameter"),
            std::string::npos);
  p.mutable_absolute_lengths()->erase("num_samples");
  (*p.mutable_absolute_lengths())["max_distance_d"] = -1.0;
  EXPECT_EQ(wire::OptionsFromProto(method, p).status().code(), absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace mlsreg
