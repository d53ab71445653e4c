#include "rve_server/common/flags.h"

#include <algorithm>

#include "absl/status/status.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"

namespace rvehub::cli {

bool WantsHelp(int argc, char** argv, int first) {
  for (int i = first; i < argc; ++i) {
    const absl::string_view arg = argv[i];
    if (arg == "--help" || arg == "-h") return true;
  }
  return false;
}

absl::CommandLineFlag* FindFlag(absl::string_view name) {
  std::string flag(name);
  std::replace(flag.begin(), flag.end(), '-', '_');
  return absl::FindCommandLineFlag(flag);
}

absl::StatusOr<Args> ParseArgs(int argc, char** argv, int first, const ArgSpec& spec) {
  Args args;
  for (int i = first; i < argc; ++i) {
    const std::string arg = argv[i];
    if (!arg.starts_with("--")) {
      if (!spec.positional) {
        return absl::InvalidArgumentError(absl::StrCat("unexpected argument '", arg, "'"));
      }
      args.positional.push_back(arg);
      continue;
    }
    const std::size_t eq = arg.find('=');
    const std::string given = arg.substr(2, eq == std::string::npos ? std::string::npos : eq - 2);
    // The old spelling has no hyphen left: a mix is a typo, not an old script.
    std::string name = given;
    if (!spec.allowed.contains(name) && !absl::StrContains(name, '-')) {
      std::replace(name.begin(), name.end(), '_', '-');
    }
    // Only the command's own options: absl's built-in ones (--flagfile,
    // --fromenv, ...) and other commands' options are unknown here.
    absl::CommandLineFlag* flag = spec.allowed.contains(name) ? FindFlag(name) : nullptr;
    if (flag == nullptr) {
      return absl::InvalidArgumentError(absl::StrCat("unknown option --", given, " (see --help)"));
    }
    if (name != given) {
      std::string warning = absl::StrCat("--", given, " is now spelled --", name);
      if (std::find(args.warnings.begin(), args.warnings.end(), warning) == args.warnings.end()) {
        args.warnings.push_back(std::move(warning));
      }
    }
    const bool is_bool = flag->IsOfType<bool>();
    if (spec.bare.contains(name) && eq != std::string::npos) {
      return absl::InvalidArgumentError(absl::StrCat("--", name, " takes no value"));
    }
    if (!is_bool && eq == std::string::npos) {
      return absl::InvalidArgumentError(
          absl::StrCat("--", name, " needs a value (--", name, "=...)"));
    }
    const std::string value = eq == std::string::npos ? "true" : arg.substr(eq + 1);
    if (spec.repeatable.contains(name)) {
      // Kept as typed: a value may hold commas, which a vector flag would split.
      args.repeated[name].push_back(value);
      continue;
    }
    std::string error;
    if (!flag->ParseFrom(value, &error)) {
      auto rule = spec.rules.find(name);
      return absl::InvalidArgumentError(
          rule != spec.rules.end() ? absl::StrCat("--", name, " ", rule->second)
                                   : absl::StrCat("bad value for --", name, ": '", value, "'"));
    }
    args.text[name] = value;
  }
  return args;
}

}  // namespace rvehub::cli
