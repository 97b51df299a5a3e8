#include "cli/registration_flags.h"

#include <string>
#include <string_view>
#include <utility>

#include "absl/strings/str_cat.h"
#include "mlsreg/registration/parameters.h"

namespace mlsreg::cli {
namespace {

// The help section of each parameter group.
constexpr std::pair<ParameterGroup, const char*> kGroupTitles[] = {
    {kCommonParameters, "Registration"},
    {kSparseIcpParameters, "Sparse ICP (auto, cp-sicp, mls-sicp, st-sicp, rc-*)"},
    {kMlsParameters, "MLS (auto, mls-sicp, st-sicp, cp-sicp+mls-sicp)"},
    {kFilterParameters, "Correspondence filters (Sparse ICP methods)"},
    {kGicpParameters, "G-ICP"},
    {kFgrParameters, "FGR"},
    {kAutoParameters, "auto (global candidates and verification)"},
};

std::string GroupTitle(ParameterGroup group) {
  for (const auto& [g, title] : kGroupTitles) {
    if (g == group) return title;
  }
  return "Registration";
}

// A length's help says it may be given in the clouds' units too: in place of "(units of d)"
// where the help names the unit, else at the end.
std::string LengthHelp(const ParameterSpec& spec, std::string help) {
  if (!spec.IsLength()) return help;
  constexpr std::string_view kInD = "(units of d)";
  constexpr std::string_view kEither = "(units of d, or a length: 1m, 30cm, 5mm)";
  if (const std::size_t at = help.find(kInD); at != std::string::npos) {
    return help.replace(at, kInD.size(), kEither);
  }
  return help + " " + std::string(kEither);
}

const char* TypeName(ParameterType type) {
  switch (type) {
    case ParameterType::kInt:
      return "INT";
    case ParameterType::kUint64:
      return "UINT";
    case ParameterType::kDouble:
      return "FLOAT";
    case ParameterType::kEnum:
      return "NAME";
    case ParameterType::kBool:
      return "";
  }
  return "";
}

}  // namespace

void RegistrationFlags::AddTo(CLI::App& app, bool method_flag) {
  if (method_flag) {
    std::string help = "registration method:";
    for (const MethodSpec& m : MethodTable())
      help += "\n  " + std::string(m.name) + ": " + std::string(m.summary);
    app.add_option("--method", method_, help)
        ->capture_default_str()
        ->group(GroupTitle(kCommonParameters));
  }
  const RegistrationOptions defaults;
  for (const ParameterSpec& spec : ParameterTable()) {
    const std::string flag = "--" + std::string(spec.flag);
    const std::string field = flag;
    CLI::Option* option;
    if (spec.type == ParameterType::kBool) {
      // A bool flag turns its parameter on, or off for a "no-" flag, whose default is on.
      const bool value = !spec.flag.starts_with("no-");
      option = app.add_flag_callback(
          flag, [this, &spec, value] { spec.set(options_, ParameterValue(value)); },
          std::string(spec.help));
    } else {
      option = app.add_option_function<std::string>(
          flag,
          [this, &spec, field](const std::string& text) {
            absl::Status set = SetParameterFromText(options_, spec, text, field);
            if (!set.ok() && error_.ok()) error_ = set;
          },
          LengthHelp(
              spec, std::string(spec.help) + (spec.type == ParameterType::kEnum
                                                  ? ": " + spec.enum_names->Choices()
                                              : spec.note.empty() ? std::string()
                                                                  : " " + std::string(spec.note))));
      option->default_str(spec.Format(spec.get(defaults)));
      option->type_name(TypeName(spec.type));
    }
    option->group(GroupTitle(spec.group));
  }
}

absl::StatusOr<RegistrationOptions> RegistrationFlags::ToOptions() const {
  if (!error_.ok()) return error_;
  RegistrationOptions options = options_;
  auto method = ParseMethod(method_);
  if (!method.ok()) return method.status();
  options.method = *method;
  if (absl::Status s = ValidateOptions(options); !s.ok()) return s;
  return options;
}

}  // namespace mlsreg::cli
