// The rve_cli tool (rve_server/cli/rve_cli.cc), run as a subprocess: usage,
// exit codes and error messages, and one short oedometer run whose CSV and
// PNG outputs are checked.
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "gtest/gtest.h"

namespace rvehub::cli {
namespace {

struct Result {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

// Runs rve_cli with `args` (already shell-quoted where needed).
Result RunCli(const std::string& args) {
  const std::string command = absl::StrCat("'", RVE_CLI_PATH, "' ", args, " 2>&1");
  Result r;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return r;
  char buffer[4096];
  std::size_t got;
  while ((got = std::fread(buffer, 1, sizeof(buffer), pipe)) > 0) r.output.append(buffer, got);
  const int status = pclose(pipe);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// A path in the test's temporary directory, unique per process.
std::string TempPath(const std::string& name) {
  return absl::StrCat(testing::TempDir(), "/cli_test_", getpid(), "_", name);
}

TEST(CliTest, HelpPrintsTheUsageAndExitsZero) {
  const Result r = RunCli("--help");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "Commands:")) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "element-test")) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "--material=NAME")) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "--out=FILE.csv")) << r.output;
  // --help after a command, too.
  const Result sub = RunCli("element-test --help");
  EXPECT_EQ(sub.exit_code, 0);
  EXPECT_EQ(sub.output, r.output);
}

TEST(CliTest, NoArgumentsIsAUsageError) {
  const Result r = RunCli("");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_TRUE(absl::StrContains(r.output, "Commands:")) << r.output;
}

TEST(CliTest, UnknownOptionExitsTwoNamingIt) {
  const std::string csv = TempPath("unknown_option.csv");
  const Result r = RunCli(absl::StrCat("element-test --bogus-flag=3 --out='", csv, "'"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "unknown option --bogus-flag")) << r.output;
  EXPECT_FALSE(std::ifstream(csv).good()) << "no output on a usage error";
}

TEST(CliTest, UnknownCommandExitsTwo) {
  const Result r = RunCli("frobnicate");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "unknown command 'frobnicate'")) << r.output;
}

TEST(CliTest, UnknownMaterialFailsWithTheKnownNames) {
  const std::string csv = TempPath("unknown_material.csv");
  const Result r = RunCli(absl::StrCat("element-test --material=no-such-sand --out='", csv, "'"));
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "unknown parameter set")) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "no-such-sand")) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "SET-dense")) << r.output;  // the known names
  EXPECT_FALSE(std::ifstream(csv).good());
}

TEST(CliTest, MaterialsListsTheParameterSets) {
  const Result r = RunCli("materials");
  EXPECT_EQ(r.exit_code, 0);
  const std::vector<std::string> lines = absl::StrSplit(r.output, '\n', absl::SkipEmpty());
  EXPECT_EQ(lines.size(), 9u) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "SET-dense\n"));
  EXPECT_TRUE(absl::StrContains(r.output, "footing-soft\n"));
}

// Reads the CSV as rows of numbers (header dropped).
std::vector<std::vector<double>> ParseRows(const std::string& csv) {
  std::vector<std::vector<double>> rows;
  const std::vector<std::string> lines = absl::StrSplit(csv, '\n', absl::SkipEmpty());
  for (std::size_t k = 1; k < lines.size(); ++k) {
    std::vector<double> row;
    for (absl::string_view cell : absl::StrSplit(lines[k], ',')) {
      double v = NAN;
      EXPECT_TRUE(absl::SimpleAtod(cell, &v)) << "line " << k << ": '" << cell << "'";
      row.push_back(v);
    }
    rows.push_back(std::move(row));
  }
  return rows;
}

// Column indices of the CSV.
constexpr int kStep = 0, kAxial = 1, kVol = 2, kSyy = 4, kShear = 15, kColumns = 16;

// One real run: prepare SET-dense (seed 3) and compress it oedometrically to
// 0.2 % axial strain (~2 s; one test so that the run happens once).
TEST(CliTest, OedometerRunWritesTheCsvAndThePlot) {
  const std::string csv_path = TempPath("oedometer.csv"), png_path = TempPath("oedometer.png");
  const Result r = RunCli(absl::StrCat("element-test --test=oedometer --material=SET-dense",
                                       " --seed=3 --strain=0.002 --out='", csv_path, "' --plot='",
                                       png_path, "'"));
  const std::string csv = ReadFile(csv_path), png = ReadFile(png_path);
  std::remove(csv_path.c_str());
  std::remove(png_path.c_str());
  ASSERT_EQ(r.exit_code, 0) << r.output;

  const std::string header = csv.substr(0, csv.find('\n'));
  EXPECT_EQ(header,
            "step,axial_strain,vol_strain,sxx,syy,sxy,p,q,void_ratio,coordination,fabric_xx,"
            "fabric_yy,fabric_xy,Fa,permeability,shear_strain");

  const std::vector<std::vector<double>> rows = ParseRows(csv);
  ASSERT_GT(rows.size(), 10u);
  for (const std::vector<double>& row : rows) {
    ASSERT_EQ(static_cast<int>(row.size()), kColumns);
    for (double v : row) EXPECT_TRUE(std::isfinite(v));
  }
  const std::vector<double>& first = rows.front();
  const std::vector<double>& last = rows.back();
  EXPECT_EQ(first[kStep], 0.0);
  EXPECT_GE(last[kAxial], 0.002);
  EXPECT_LT(last[kAxial], 0.0025);  // stops at the first row past the target
  EXPECT_GT(last[kSyy], first[kSyy]);
  for (std::size_t k = 1; k < rows.size(); ++k) {
    EXPECT_GT(rows[k][kStep], rows[k - 1][kStep]) << "row " << k;
    EXPECT_GE(rows[k][kAxial], rows[k - 1][kAxial]) << "row " << k;
    // Oedometer: ε_xx = 0, so ε_vol = 1 − det F = 1 − F_yy = ε_axial (to the
    // 10 significant digits of the CSV), and there is no shear.
    EXPECT_NEAR(rows[k][kVol], rows[k][kAxial], 1e-9 * std::abs(rows[k][kAxial]) + 1e-15);
    EXPECT_EQ(rows[k][kShear], 0.0);
  }

  const std::string signature = "\x89PNG\r\n\x1a\n";
  ASSERT_GE(png.size(), signature.size());
  EXPECT_EQ(png.substr(0, signature.size()), signature);
  EXPECT_GT(png.size(), 1000u);  // a real image, not just a header
}

}  // namespace
}  // namespace rvehub::cli
