// The command-line convention of every binary (rve_server/common/flags.h):
// options are spelled with hyphens; the old underscore spelling still works,
// with a warning naming the new one; anything else is an unknown option.
// ParseArgs itself, then mpm_client and rve_cli printing its warnings
// (rve_server's: server_process_test).
#include "rve_server/common/flags.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "absl/flags/flag.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "tests/support/process_util.h"

ABSL_FLAG(std::string, checkpoint_dir, "", "test: a string option");
ABSL_FLAG(int64_t, max_memory_mb, 16, "test: an integer option");
ABSL_FLAG(bool, no_recovery, false, "test: a bare switch");
ABSL_FLAG(std::vector<std::string>, set, {}, "test: a repeatable option");
ABSL_FLAG(int, threads, 0, "test: an option without underscores");
ABSL_FLAG(int, hidden_option, 0, "test: a flag the spec does not allow");

namespace rvehub::cli {
namespace {

// ParseArgs on `args` (argv[0] is the program), with every option above
// allowed but hidden-option.
absl::StatusOr<Args> Parse(std::vector<std::string> args) {
  ArgSpec spec;
  spec.allowed = {"checkpoint-dir", "max-memory-mb", "no-recovery", "set", "threads"};
  spec.repeatable = {"set"};
  spec.bare = {"no-recovery"};
  spec.rules = {{"max-memory-mb", "must be a whole number of MiB"}};
  args.insert(args.begin(), "program");
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  return ParseArgs(static_cast<int>(argv.size()), argv.data(), 1, spec);
}

void ResetFlags() {
  absl::SetFlag(&FLAGS_checkpoint_dir, "");
  absl::SetFlag(&FLAGS_max_memory_mb, 16);
  absl::SetFlag(&FLAGS_no_recovery, false);
}

TEST(ParseArgs, HyphenSpellingWithoutWarning) {
  ResetFlags();
  const absl::StatusOr<Args> args =
      Parse({"--checkpoint-dir=/x", "--max-memory-mb=64", "--no-recovery", "--threads=2", "pos"});
  ASSERT_TRUE(args.ok()) << args.status();
  EXPECT_TRUE(args->warnings.empty());
  EXPECT_EQ(args->text.at("checkpoint-dir"), "/x");
  EXPECT_EQ(absl::GetFlag(FLAGS_checkpoint_dir), "/x");
  EXPECT_EQ(absl::GetFlag(FLAGS_max_memory_mb), 64);
  EXPECT_TRUE(absl::GetFlag(FLAGS_no_recovery));
  EXPECT_EQ(args->positional, std::vector<std::string>{"pos"});
}

TEST(ParseArgs, UnderscoreSpellingWorksWithAWarning) {
  ResetFlags();
  const absl::StatusOr<Args> ok = Parse(
      {"--checkpoint_dir=/x", "--max_memory_mb=64", "--no_recovery", "--set=a=1", "--threads=3"});
  ASSERT_TRUE(ok.ok()) << ok.status();
  EXPECT_EQ(ok->warnings, (std::vector<std::string>{
                              "--checkpoint_dir is now spelled --checkpoint-dir",
                              "--max_memory_mb is now spelled --max-memory-mb",
                              "--no_recovery is now spelled --no-recovery",
                          }));
  // Kept under the new spelling, and the flags hold the values.
  EXPECT_EQ(ok->text.at("checkpoint-dir"), "/x");
  EXPECT_FALSE(ok->text.contains("checkpoint_dir"));
  EXPECT_EQ(absl::GetFlag(FLAGS_checkpoint_dir), "/x");
  EXPECT_EQ(absl::GetFlag(FLAGS_max_memory_mb), 64);
  EXPECT_TRUE(absl::GetFlag(FLAGS_no_recovery));
}

TEST(ParseArgs, OneWarningPerOldName) {
  const absl::StatusOr<Args> args = Parse({"--checkpoint_dir=/a", "--checkpoint_dir=/b"});
  ASSERT_TRUE(args.ok()) << args.status();
  EXPECT_EQ(args->warnings,
            std::vector<std::string>{"--checkpoint_dir is now spelled --checkpoint-dir"});
  EXPECT_EQ(args->text.at("checkpoint-dir"), "/b");
}

// The old spelling is checked as the new one is; messages name the new one.
TEST(ParseArgs, UnderscoreSpellingIsCheckedAsTheHyphenOne) {
  absl::StatusOr<Args> args = Parse({"--max_memory_mb=lots"});
  ASSERT_FALSE(args.ok());
  EXPECT_EQ(args.status().message(), "--max-memory-mb must be a whole number of MiB");
  args = Parse({"--no_recovery=true"});
  ASSERT_FALSE(args.ok());
  EXPECT_EQ(args.status().message(), "--no-recovery takes no value");
  args = Parse({"--checkpoint_dir"});
  ASSERT_FALSE(args.ok());
  EXPECT_EQ(args.status().message(), "--checkpoint-dir needs a value (--checkpoint-dir=...)");
}

TEST(ParseArgs, UnknownNamesAreRefused) {
  for (const char* name : {"bogus", "checkpoint", "checkpoint-dir-x", "hidden-option",
                           "hidden_option", "Checkpoint_Dir", "checkpoint__dir", "set_"}) {
    const absl::StatusOr<Args> args = Parse({absl::StrCat("--", name, "=1")});
    ASSERT_FALSE(args.ok()) << name;
    EXPECT_EQ(args.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_EQ(args.status().message(), absl::StrCat("unknown option --", name, " (see --help)"));
  }
}

// A mix of hyphens and underscores is neither the old spelling nor the new:
// a typo, refused as unknown rather than guessed at.
TEST(ParseArgs, MixedSpellingIsUnknown) {
  for (const char* name : {"max_memory-mb", "max-memory_mb"}) {
    const absl::StatusOr<Args> args = Parse({absl::StrCat("--", name, "=64")});
    ASSERT_FALSE(args.ok()) << name;
    EXPECT_EQ(args.status().message(), absl::StrCat("unknown option --", name, " (see --help)"));
  }
}

// The binaries print the warning on stderr, one line per old name, and go
// on (here to a failure of their own: a file that does not exist, exit 1).
TEST(OldSpelling, MpmClientWarnsAndGoesOn) {
  const testing_util::CommandResult r = testing_util::RunCommand(absl::StrCat(
      "'", MPM_CLIENT_PATH, "' resume /nonexistent/checkpoint.h5 --stop_after=3 --quiet 2>&1"));
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_TRUE(
      absl::StrContains(r.out, "mpm_client: warning: --stop_after is now spelled --stop-after\n"))
      << r.out;
  EXPECT_TRUE(absl::StrContains(r.out, "/nonexistent/checkpoint.h5")) << r.out;
}

TEST(OldSpelling, RveCliWarnsAndGoesOn) {
  const testing_util::CommandResult r = testing_util::RunCommand(
      absl::StrCat("'", RVE_CLI_PATH,
                   "' info --server=127.0.0.1:1 --token_file=/nonexistent/token --timeout=1 2>&1"));
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_TRUE(
      absl::StrContains(r.out, "rve_cli: warning: --token_file is now spelled --token-file\n"))
      << r.out;
  EXPECT_TRUE(absl::StrContains(r.out, "/nonexistent/token")) << r.out;
}

}  // namespace
}  // namespace rvehub::cli
