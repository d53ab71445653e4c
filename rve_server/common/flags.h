// Command lines of RVEHub's binaries, read with Abseil flags. Each binary
// defines its options with ABSL_FLAG (types, values, help); ParseArgs matches
// argv against them and hands back the positional arguments. Unlike
// absl::ParseCommandLine it returns errors as values (the binaries exit 2 on
// a usage error; absl exits 1), leaves --help to the caller (its own usage
// text, exit 0), accepts only the options a command names, spells names with
// hyphens (--stop-after reads FLAGS_stop_after) and can collect every value
// of a repeatable option. The underscore spelling that rve_server once took
// (--checkpoint_dir) still works, with a warning naming the hyphen one, so
// that existing scripts and manifests keep running.
#ifndef RVEHUB_RVE_SERVER_COMMON_FLAGS_H_
#define RVEHUB_RVE_SERVER_COMMON_FLAGS_H_

#include <map>
#include <set>
#include <string>
#include <vector>

#include "absl/flags/commandlineflag.h"
#include "absl/flags/reflection.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/types/optional.h"

namespace rvehub::cli {

struct ArgSpec {
  std::set<std::string> allowed;     // option names accepted, hyphen spelling
  std::set<std::string> repeatable;  // every occurrence kept (Args::repeated)
  // Switches that take no "=value" (else a bool takes --x, --x=true|false).
  std::set<std::string> bare;
  // "--NAME <rule>" is the message for a value NAME's flag cannot parse
  // (default "bad value for --NAME: 'VALUE'").
  std::map<std::string, std::string> rules;
  bool positional = true;  // positional arguments allowed
};

struct Args {
  std::vector<std::string> positional;
  // Keys here and in `repeated` are the hyphen spelling, however given.
  std::map<std::string, std::string> text;  // the last value given of each option
  std::map<std::string, std::vector<std::string>> repeated;
  // One line per option given in its old underscore spelling, for the binary
  // to print: "--checkpoint_dir is now spelled --checkpoint-dir".
  std::vector<std::string> warnings;
  bool contains(const std::string& name) const {
    return text.contains(name) || repeated.contains(name);
  }
};

// --help or -h anywhere from argv[first] on (it wins over everything else).
bool WantsHelp(int argc, char** argv, int first);

// Parses argv[first..] ("--name=value", "--switch", positionals); the parsed
// values are set on the binary's ABSL_FLAGs. An allowed option given with
// underscores for all its hyphens is taken, with a warning; a mix of the two
// (--max_memory-mb) is neither spelling and unknown. InvalidArgument with a
// message for people on an unknown option, a missing or unparsable value, or
// a positional argument where none is allowed.
absl::StatusOr<Args> ParseArgs(int argc, char** argv, int first, const ArgSpec& spec);

// The ABSL_FLAG behind option `name` (hyphen spelling); nullptr if none.
absl::CommandLineFlag* FindFlag(absl::string_view name);

// The value of option `name` as its flag holds it (after ParseArgs); nullopt
// when there is no such flag of type T (a programming error).
template <typename T>
absl::optional<T> FlagValue(absl::string_view name) {
  absl::CommandLineFlag* flag = FindFlag(name);
  if (flag == nullptr) return absl::nullopt;
  return flag->TryGet<T>();
}

}  // namespace rvehub::cli

#endif  // RVEHUB_RVE_SERVER_COMMON_FLAGS_H_
