// The rve_cli tool (rve_server/cli/rve_cli.cc), run as a subprocess: usage,
// exit codes and error messages, one short oedometer run whose CSV and PNG
// outputs are checked, and the server commands against real rve_server
// processes on free loopback ports (templates, an element test on the server
// bit-identical to the local one, get, checkpoint and restore).
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "gtest/gtest.h"
#include "nlohmann/json.hpp"
#include "rve_server/client/channel.h"
#include "rve_server/client/remote_server.h"
#include "rve_server/service/registry.h"
#include "rvehub/v1/rve_service.grpc.pb.h"
#include "tests/process_util.h"

namespace rvehub::cli {
namespace {

using testing_util::ReadFile;

struct Result {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

// Runs rve_cli with `args` (already shell-quoted where needed); `output` has
// stdout and stderr together, or stdout only when `stdout_only`.
Result RunCli(const std::string& args, bool stdout_only = false) {
  testing_util::CommandResult r = testing_util::RunCommand(
      absl::StrCat("'", RVE_CLI_PATH, "' ", args, stdout_only ? " 2>/dev/null" : " 2>&1"));
  return {r.exit_code, std::move(r.out)};
}

// A path in the test's temporary directory, unique per process.
std::string TempPath(const std::string& name) {
  return absl::StrCat(testing::TempDir(), "/cli_test_", getpid(), "_", name);
}

const char* const kCommands[] = {"element-test",    "prepare",    "materials", "info",      "get",
                                 "upload-template", "checkpoint", "restore",   "list-runs", "drop"};
const char* const kServerCommands[] = {
    "info", "get", "upload-template", "checkpoint", "restore", "list-runs", "drop"};

TEST(CliTest, HelpPrintsTheUsageAndExitsZero) {
  const Result r = RunCli("--help");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "Commands:")) << r.output;
  for (const char* command : kCommands) {
    EXPECT_TRUE(absl::StrContains(r.output, absl::StrCat("\n  ", command, " "))) << command;
  }
  EXPECT_TRUE(absl::StrContains(r.output, "--server=HOST:PORT")) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "--timeout=SECONDS")) << r.output;
}

TEST(CliTest, EveryCommandHasItsOwnHelp) {
  for (const char* command : kCommands) {
    const Result r = RunCli(absl::StrCat(command, " --help"));
    EXPECT_EQ(r.exit_code, 0) << command << ": " << r.output;
    EXPECT_TRUE(absl::StrContains(r.output, absl::StrCat("rve_cli ", command, " ")))
        << command << ": " << r.output;
    EXPECT_FALSE(absl::StrContains(r.output, "Commands:")) << command << ": not the usage";
    // `help COMMAND` is the same text, and --help wins over other options.
    EXPECT_EQ(RunCli(absl::StrCat("help ", command)).output, r.output) << command;
    EXPECT_EQ(RunCli(absl::StrCat(command, " --bogus=1 --help")).output, r.output) << command;
  }
  for (const char* command : kServerCommands) {
    const Result r = RunCli(absl::StrCat(command, " --help"));
    for (const char* option :
         {"--server=HOST:PORT", "--token-file=FILE", "--tls-ca=FILE", "--timeout=SECONDS"}) {
      EXPECT_TRUE(absl::StrContains(r.output, option)) << command << " lacks " << option;
    }
  }
  const Result element_test = RunCli("element-test --help");
  for (const char* option : {"--material=NAME", "--out=FILE.csv", "--template=NAME",
                             "--server=HOST:PORT", "--cyclic-control"}) {
    EXPECT_TRUE(absl::StrContains(element_test.output, option)) << option;
  }
  EXPECT_TRUE(absl::StrContains(RunCli("prepare --help").output, "--out=FILE.h5"));
  EXPECT_TRUE(absl::StrContains(RunCli("get --help").output, "--format=FORMAT"));
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

// rve_server and mpm_client answer --help like rve_cli: usage on stdout,
// exit 0, no build paths (absl's own --help exits 1 and prints them).
TEST(CliTest, EveryBinaryHelpExitsZeroWithoutBuildPaths) {
  for (const std::string& binary :
       {std::string(RVE_SERVER_PATH), std::string(MPM_CLIENT_PATH), std::string(RVE_CLI_PATH)}) {
    for (const char* flag : {"--help", "-h"}) {
      const testing_util::CommandResult r =
          testing_util::RunCommand(absl::StrCat("'", binary, "' ", flag, " 2>&1"));
      EXPECT_EQ(r.exit_code, 0) << binary << " " << flag << ": " << r.out;
      EXPECT_TRUE(absl::StrContains(r.out, "Usage")) << binary << ": " << r.out;
      EXPECT_FALSE(absl::StrContains(r.out, RVEHUB_SOURCE_DIR)) << binary << ": " << r.out;
      EXPECT_FALSE(absl::StrContains(r.out, ".cc")) << binary << ": " << r.out;
    }
  }
  const testing_util::CommandResult server =
      testing_util::RunCommand(absl::StrCat("'", RVE_SERVER_PATH, "' --help"));
  for (const char* flag : {"--listen=127.0.0.1:50051", "--threads=0", "--checkpoint-dir=",
                           "--auth-token-file=", "--tls-cert=", "--drain-seconds=30"}) {
    EXPECT_TRUE(absl::StrContains(server.out, flag)) << flag << " in\n" << server.out;
  }
}

// A template file that cannot be written (a file size limit, as a full
// disk) fails with the file named, exit 1, and no crash at exit.
TEST(CliTest, FailedWriteExitsOneWithoutCrashing) {
  const std::string file = TempPath("too_big.h5");
  // SIGXFSZ ignored: writes past 40 blocks of 512 bytes fail with EFBIG.
  const testing_util::CommandResult r = testing_util::RunCommand(absl::StrCat(
      "trap '' XFSZ; ulimit -f 40; '", RVE_CLI_PATH, "' prepare --out='", file, "' 2>&1"));
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_TRUE(absl::StrContains(r.out, absl::StrCat("writing ", file))) << r.out;
  EXPECT_FALSE(std::ifstream(file).good());
}

// rve_server whose checkpoint on SIGTERM cannot be written (a file size
// limit, as a full disk) exits 1 rather than crashing in HDF5's cleanup.
TEST(CliTest, ServerWithAFailedCheckpointExitsOne) {
  const std::string dir = TempPath("server_checkpoint");
  std::filesystem::create_directories(dir);
  // The limit applies to the server only, through a wrapper that execs it.
  const std::string wrapper = TempPath("limited_server.sh");
  std::ofstream(wrapper) << "#!/bin/sh\ntrap '' XFSZ\nulimit -f 40\nexec '" << RVE_SERVER_PATH
                         << "' \"$@\"\n";
  std::filesystem::permissions(wrapper, std::filesystem::perms::owner_all);
  testing_util::ServerProcess server(wrapper, TempPath("limited_server.log"),
                                     {absl::StrCat("--checkpoint-dir=", dir)});
  ASSERT_FALSE(server.address().empty()) << server.Log();
  // A template (66 KB) to checkpoint: upload one prepared here.
  const std::string file = TempPath("limited_template.h5");
  ASSERT_EQ(RunCli(absl::StrCat("prepare --out='", file, "'")).exit_code, 0);
  const Result upload =
      RunCli(absl::StrCat("upload-template --server=", server.address(), " --file='", file, "'"));
  ASSERT_EQ(upload.exit_code, 0) << upload.output;
  EXPECT_EQ(server.Stop(), 1) << server.Log();
  EXPECT_TRUE(absl::StrContains(server.Log(), "templates.h5")) << server.Log();
  std::filesystem::remove_all(dir);
  std::remove(file.c_str());
  std::remove(wrapper.c_str());
}

// A header and one line per set with its parameters (cases/REFERENCE.md).
TEST(CliTest, MaterialsListsTheParameterSets) {
  const Result r = RunCli("materials");
  EXPECT_EQ(r.exit_code, 0);
  const std::vector<std::string> lines = absl::StrSplit(r.output, '\n', absl::SkipEmpty());
  ASSERT_EQ(lines.size(), 14u) << r.output;  // the header and 13 sets
  EXPECT_TRUE(lines[0].starts_with("NAME ")) << lines[0];
  for (const char* column : {" E_MPA ", " MU ", " RMIN_MM ", " P0_KPA ", " E0 "}) {
    EXPECT_TRUE(absl::StrContains(lines[0], column)) << column << " in " << lines[0];
  }
  // SET-dense: linear contacts, E = 600 MPa, μ = 0.5452, 400 discs of 3-7 mm,
  // p0 = 100 kPa, e0 = 0.177; footing-soft: E = 80 MPa, rolling η = 0.02,
  // prepared at the footing's 20 kPa.
  std::vector<std::string> dense = absl::StrSplit(lines[1], ' ', absl::SkipEmpty());
  EXPECT_EQ(dense, (std::vector<std::string>{"SET-dense", "linear", "2650", "600", "0.8", "0.25",
                                             "0.5452", "0", "0", "0", "0.1", "0.1", "400", "3", "7",
                                             "100", "0.177", "0.001"}))
      << lines[1];
  std::string soft;
  for (const std::string& line : lines) {
    if (line.starts_with("footing-soft ")) soft = line;
  }
  std::vector<std::string> soft_fields = absl::StrSplit(soft, ' ', absl::SkipEmpty());
  ASSERT_EQ(soft_fields.size(), 18u) << soft;
  EXPECT_EQ(soft_fields[3], "80");
  EXPECT_EQ(soft_fields[8], "0.02");
  EXPECT_EQ(soft_fields[15], "20");
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

// ---------------------------------------------------------------------------
// Usage errors of the server commands (no server needed).

TEST(CliTest, ServerCommandsWithoutServerAreUsageErrors) {
  const std::string missing = TempPath("missing.h5");
  for (const std::string& args : {std::string("info"), std::string("get --run=a --id=1"),
                                  absl::StrCat("checkpoint --out='", missing, "'"),
                                  absl::StrCat("restore --file='", missing, "'"),
                                  absl::StrCat("upload-template --file='", missing, "'")}) {
    const Result r = RunCli(args);
    EXPECT_EQ(r.exit_code, 2) << args << ": " << r.output;
    EXPECT_TRUE(absl::StrContains(r.output, "--server=HOST:PORT is required")) << r.output;
  }
  const std::string csv = TempPath("usage.csv");
  struct Case {
    std::string args, message;
  };
  for (const Case& c : std::vector<Case>{
           {"element-test --template=t", "--template needs --server"},
           {"element-test --server=127.0.0.1:1", "--template=NAME is required with --server"},
           {"element-test --server=127.0.0.1:1 --template=t --material=SET-dense",
            "--material does not apply with --server (the template fixes the packing)"},
           {"element-test --server=127.0.0.1:1 --template=t --pressure=5000",
            "--pressure does not apply with --server (the template fixes the packing)"},
           {"element-test --server=127.0.0.1:1 --template=t --void-ratio=0.25",
            "--void-ratio does not apply with --server (the template fixes the packing)"},
           {"prepare --pressure=0", "--pressure must be a pressure in (0, 1e9] Pa"},
           {"element-test --pressure=2e9", "--pressure must be a pressure in"},
           {"prepare --void-ratio=0", "--void-ratio must lie in (0, 1)"},
           {"element-test --void-ratio=1.5", "--void-ratio must lie in (0, 1)"},
           {"element-test --server=127.0.0.1:1 --template=t --particles=1600",
            "--particles does not apply with --server (the template fixes the packing)"},
           {"prepare --particles=1", "--particles must lie in [2, 1000000]"},
           {"element-test --server=127.0.0.1:1 --template=t --rolling-eta=0.02",
            "--rolling-eta does not apply with --server"},
           {"prepare --material=footing-dense --rolling-eta=-0.01",
            "--rolling-eta must lie in [0, 1]"},
           {"element-test --material=footing-dense --rolling-eta=1.5",
            "--rolling-eta must lie in [0, 1]"},
           {"element-test --particles=2000000", "--particles must lie in [2, 1000000]"},
           {"element-test --axis=z", "--axis must be x or y"},
           {"element-test --test=isotropic --axis=x",
            "--axis applies to drained-biaxial and oedometer only"},
           {"element-test --amplitude=-1e308", "--amplitude applies to cyclic-simple-shear only"},
           {"element-test --test=oedometer --cycles=3",
            "--cycles applies to cyclic-simple-shear only"},
           {"element-test --test=undrained-simple-shear --cyclic-control=stress",
            "--cyclic-control applies to cyclic-simple-shear only"},
           {"get --server=127.0.0.1:1 --id=1", "--run=RUN is required"},
           {"get --server=127.0.0.1:1 --run=a", "--id=N is required"},
           {"get --server=127.0.0.1:1 --run=a --id=x", "bad value for --id"},
           {"get --server=127.0.0.1:1 --run=a --id=1 --format=xml", "--format must be"},
           {"get --server=127.0.0.1:1 --run=a --id=1 --timeout=-1", "--timeout"},
           {"checkpoint --server=127.0.0.1:1", "--out=FILE.h5 is required"},
           {"restore --server=127.0.0.1:1", "--file=FILE.h5 is required"},
           {"prepare --name=x", "--name needs --out"},
           {"prepare --out=x.h5 --name=bad/name", "--name"},
           {"info --server=127.0.0.1:1 --run=a", "unknown option --run"},
           // gRPC would dial port 70000 − 65536 = 4464.
           {"info --server=127.0.0.1:70000",
            "--server: \"127.0.0.1:70000\" is not HOST:PORT with a port in 1..65535"},
       }) {
    const std::string args =
        c.args.starts_with("element-test") ? absl::StrCat(c.args, " --out='", csv, "'") : c.args;
    const Result r = RunCli(args);
    EXPECT_EQ(r.exit_code, 2) << c.args << ": " << r.output;
    EXPECT_TRUE(absl::StrContains(r.output, c.message)) << c.args << ": " << r.output;
  }
  EXPECT_FALSE(std::ifstream(csv).good());
}

TEST(CliTest, UnreachableServerFailsNamingUnavailable) {
  const Result r = RunCli("info --server=127.0.0.1:1 --timeout=10");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "UNAVAILABLE: ")) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "127.0.0.1:1")) << r.output;
}

// ---------------------------------------------------------------------------
// Against real servers.

// A running rve_server (testing_util::ServerProcess) and a stub on it; its
// log is removed at destruction unless the test failed.
class Server {
 public:
  explicit Server(std::vector<std::string> extra_args = {})
      : process_(RVE_SERVER_PATH, NextLogPath(), std::move(extra_args)),
        stub_(v1::RveService::NewStub(client::MakeChannel(process_.address(), {}))) {}
  ~Server() {
    Stop();
    if (!testing::Test::HasFailure()) std::remove(process_.log_path().c_str());
  }
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  // SIGTERM and wait; the exit status (−1 when it did not exit normally).
  int Stop() {
    // Our idle connection would hold the server's drain up for seconds.
    stub_.reset();
    return process_.Stop();
  }

  const std::string& address() const { return process_.address(); }
  std::string server_flag() const { return absl::StrCat("--server=", address()); }
  v1::RveService::Stub& stub() { return *stub_; }
  std::string Log() const { return process_.Log(); }

 private:
  static std::string NextLogPath() {
    static int count = 0;
    return TempPath(absl::StrCat("server", ++count, ".log"));
  }

  testing_util::ServerProcess process_;
  std::unique_ptr<v1::RveService::Stub> stub_;
};

std::unique_ptr<grpc::ClientContext> Ctx() {
  auto ctx = std::make_unique<grpc::ClientContext>();
  client::Prepare(*ctx, {}, std::chrono::seconds(60));
  return ctx;
}

// rve_cli prepare --particles: the count printed and in the template's
// default name, so that it is not taken for the set's own packing.
TEST(CliTest, PrepareWithAnotherParticleCountNamesIt) {
  const std::string file = TempPath("template-100discs.h5");
  const Result r = RunCli(
      absl::StrCat("prepare --material=SET-dense --seed=2 --particles=100 --out='", file, "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "\nparticles 100\n")) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "template SET-dense-seed2-100discs\n")) << r.output;
  std::filesystem::remove(file);
}

// Likewise another compaction pressure or void ratio: each makes another
// packing, so the default name carries it (the name mpm_client's template
// cache gives the same preparation).
TEST(CliTest, PrepareAtAnotherPressureAndVoidRatioNamesThem) {
  const std::string file = TempPath("template-p-e.h5");
  const Result r = RunCli(absl::StrCat(
      "prepare --material=SET-dense --seed=2 --pressure=20000 --void-ratio=0.25 --particles=100 "
      "--out='",
      file, "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "template SET-dense-seed2-p20000Pa-e0.25-100discs\n"))
      << r.output;
  std::filesystem::remove(file);
}

// And another rolling-resistance η: another material, named as such. A set
// without rolling resistance refuses it (η would change nothing there).
TEST(CliTest, PrepareWithAnotherRollingEtaNamesIt) {
  const std::string file = TempPath("template-eta.h5");
  const Result r = RunCli(absl::StrCat(
      "prepare --material=footing-dense --seed=2 --particles=100 --rolling-eta=0.02 --out='", file,
      "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "template footing-dense-seed2-100discs-eta0.02\n"))
      << r.output;
  std::filesystem::remove(file);
  const Result refused = RunCli("prepare --material=SET-dense --particles=100 --rolling-eta=0.02");
  EXPECT_EQ(refused.exit_code, 1) << refused.output;
  EXPECT_TRUE(absl::StrContains(refused.output, "SET-dense, which has no rolling resistance"))
      << refused.output;
}

// rve_cli prepare --out (SET-dense, ~0.5 s) and upload-template; the name.
std::string PrepareAndUpload(const Server& server, int seed) {
  const std::string file = TempPath(absl::StrCat("template", seed, ".h5"));
  const Result prepared =
      RunCli(absl::StrCat("prepare --material=SET-dense --seed=", seed, " --out='", file, "'"));
  EXPECT_EQ(prepared.exit_code, 0) << prepared.output;
  const std::string name = absl::StrCat("SET-dense-seed", seed);
  EXPECT_TRUE(absl::StrContains(prepared.output, absl::StrCat("template ", name, "\n")))
      << prepared.output;
  const Result uploaded =
      RunCli(absl::StrCat("upload-template ", server.server_flag(), " --file='", file, "'"));
  EXPECT_EQ(uploaded.exit_code, 0) << uploaded.output;
  std::remove(file.c_str());
  return name;
}

void CreateRves(Server& server, const std::string& run, const std::string& template_name,
                const std::vector<std::int64_t>& ids) {
  v1::CreateRvesRequest request;
  request.set_run_id(run);
  request.set_template_name(template_name);
  for (std::int64_t id : ids) request.add_ids(id);
  v1::CreateRvesResponse response;
  const grpc::Status s = server.stub().CreateRves(Ctx().get(), request, &response);
  ASSERT_TRUE(s.ok()) << s.error_message();
}

// Commits `step` for `ids` with a small compression; the results.
v1::ApplyResponse Compress(Server& server, const std::string& run, std::int64_t step,
                           const std::vector<std::int64_t>& ids) {
  v1::ApplyRequest request;
  request.set_run_id(run);
  request.set_step(step);
  request.set_mode(v1::APPLY_MODE_COMMIT);
  request.mutable_options()->set_want_tangent(true);
  for (std::int64_t id : ids) {
    v1::Increment* inc = request.add_increments();
    inc->set_id(id);
    for (double v : {1.0, 0.0, 0.0, 0.0, 1.0 - 1e-4, 0.0, 0.0, 0.0, 1.0}) inc->add_delta_f(v);
  }
  v1::ApplyResponse response;
  const grpc::Status s = server.stub().Apply(Ctx().get(), request, &response);
  EXPECT_TRUE(s.ok()) << s.error_message();
  EXPECT_EQ(response.failed(), 0);
  return response;
}

// The serialized records of a run, one Export call per RVE (so that the
// server's own chunking does not matter here).
std::vector<std::string> ExportRun(Server& server, const std::string& run,
                                   const std::vector<std::int64_t>& ids) {
  std::vector<std::string> records;
  for (std::int64_t id : ids) {
    v1::ExportRequest request;
    request.set_run_id(run);
    request.add_ids(id);
    auto ctx = Ctx();
    auto reader = server.stub().Export(ctx.get(), request);
    v1::RveChunk chunk;
    while (reader->Read(&chunk)) {
      for (const v1::RveRecord& r : chunk.records()) records.push_back(r.SerializeAsString());
    }
    const grpc::Status s = reader->Finish();
    EXPECT_TRUE(s.ok()) << s.error_message();
  }
  return records;
}

// Same bits, value by value.
void ExpectSameBits(const std::vector<std::vector<double>>& a,
                    const std::vector<std::vector<double>>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    ASSERT_EQ(a[k].size(), b[k].size()) << "row " << k;
    for (std::size_t c = 0; c < a[k].size(); ++c) {
      EXPECT_EQ(std::memcmp(&a[k][c], &b[k][c], sizeof(double)), 0)
          << "row " << k << " column " << c << ": " << a[k][c] << " vs " << b[k][c];
    }
  }
}

// prepare --out, upload-template, info, and an isotropic test on the server
// that matches the local run of the same material and seed bit for bit.
TEST(CliServerTest, ElementTestOnTheServerMatchesTheLocalRun) {
  Server server;
  ASSERT_FALSE(server.address().empty());
  const std::string name = PrepareAndUpload(server, 1);

  const std::string file = TempPath("template1_again.h5");
  ASSERT_EQ(RunCli(absl::StrCat("prepare --seed=1 --out='", file, "' --name=renamed")).exit_code,
            0);
  const Result again =
      RunCli(absl::StrCat("upload-template ", server.server_flag(), " --file='", file, "'"));
  EXPECT_EQ(again.exit_code, 0) << again.output;
  EXPECT_TRUE(absl::StrContains(again.output, "uploaded renamed: 400 particles")) << again.output;
  const Result duplicate =
      RunCli(absl::StrCat("upload-template ", server.server_flag(), " --file='", file, "'"));
  EXPECT_EQ(duplicate.exit_code, 1) << duplicate.output;
  EXPECT_TRUE(absl::StrContains(duplicate.output, "ALREADY_EXISTS: ")) << duplicate.output;
  const Result replaced = RunCli(
      absl::StrCat("upload-template ", server.server_flag(), " --file='", file, "' --replace"));
  EXPECT_EQ(replaced.exit_code, 0) << replaced.output;
  std::remove(file.c_str());

  const Result info = RunCli(absl::StrCat("info ", server.server_flag()), true);
  EXPECT_EQ(info.exit_code, 0) << info.output;
  for (const std::string& part :
       {std::string("version    0.3.0 (rvehub.v1)"), std::string("threads    1\n"),
        std::string("templates: 2\n"), std::string("runs: 0\n"), absl::StrCat("  ", name, " "),
        std::string("  renamed "), std::string(" 400 "),
        std::string("material SET-dense, seed 1")}) {
    EXPECT_TRUE(absl::StrContains(info.output, part)) << "no '" << part << "' in\n" << info.output;
  }

  const std::string test = "--test=isotropic --strain=0.01 --rows=20";
  const std::string remote_csv = TempPath("remote.csv"), local_csv = TempPath("local.csv");
  const std::string png = TempPath("remote.png");
  const Result remote =
      RunCli(absl::StrCat("element-test ", server.server_flag(), " --template=", name, " ", test,
                          " --out='", remote_csv, "' --plot='", png, "'"));
  ASSERT_EQ(remote.exit_code, 0) << remote.output;
  EXPECT_TRUE(absl::StrContains(remote.output, "100%")) << remote.output;
  const Result local = RunCli(absl::StrCat("element-test --material=SET-dense --seed=1 ", test,
                                           " --out='", local_csv, "'"));
  ASSERT_EQ(local.exit_code, 0) << local.output;
  const std::string remote_text = ReadFile(remote_csv), local_text = ReadFile(local_csv);
  const std::string png_bytes = ReadFile(png);
  std::remove(remote_csv.c_str());
  std::remove(local_csv.c_str());
  std::remove(png.c_str());
  const std::vector<std::vector<double>> remote_rows = ParseRows(remote_text);
  ASSERT_GT(remote_rows.size(), 5u);
  ExpectSameBits(remote_rows, ParseRows(local_text));
  EXPECT_EQ(remote_text, local_text);
  EXPECT_GE(remote_rows.back()[kVol], 0.01);
  EXPECT_EQ(png_bytes.substr(0, 4), "\x89PNG");

  // A test along x travels to the server as well: the same rows as locally.
  const std::string along_x = "--test=oedometer --axis=x --strain=0.001 --rows=10";
  const Result remote_x =
      RunCli(absl::StrCat("element-test ", server.server_flag(), " --template=", name, " ", along_x,
                          " --out='", remote_csv, "'"));
  ASSERT_EQ(remote_x.exit_code, 0) << remote_x.output;
  const Result local_x = RunCli(absl::StrCat("element-test --material=SET-dense --seed=1 ", along_x,
                                             " --out='", local_csv, "'"));
  ASSERT_EQ(local_x.exit_code, 0) << local_x.output;
  const std::string remote_x_text = ReadFile(remote_csv), local_x_text = ReadFile(local_csv);
  std::remove(remote_csv.c_str());
  std::remove(local_csv.c_str());
  EXPECT_EQ(remote_x_text, local_x_text);
  const std::vector<std::vector<double>> x_rows = ParseRows(remote_x_text);
  ASSERT_GT(x_rows.size(), 5u);
  // Along x the axial strain is 1 − F_xx and equals the volumetric one.
  EXPECT_GE(x_rows.back()[kAxial], 0.001);
  EXPECT_NEAR(x_rows.back()[kVol], x_rows.back()[kAxial], 1e-9);
  EXPECT_NE(remote_x_text, remote_text);

  const Result unknown = RunCli(absl::StrCat("element-test ", server.server_flag(),
                                             " --template=nope --out='", remote_csv, "'"));
  EXPECT_EQ(unknown.exit_code, 1) << unknown.output;
  EXPECT_TRUE(absl::StrContains(
      unknown.output,
      absl::StrCat("NOT_FOUND: RVE server ", server.address(), ": unknown template \"nope\"")))
      << unknown.output;
  EXPECT_FALSE(std::ifstream(remote_csv).good());
  EXPECT_EQ(server.Stop(), 0) << server.Log();
}

// list-runs shows what a server hosts; drop frees one RVE or a whole run.
TEST(CliServerTest, ListRunsAndDrop) {
  Server server;
  ASSERT_FALSE(server.address().empty());
  const std::string name = PrepareAndUpload(server, 2);
  CreateRves(server, "keep", name, {1});
  CreateRves(server, "gone", name, {5, 6});
  Compress(server, "gone", 1, {5});
  const std::string list = absl::StrCat("list-runs ", server.server_flag());
  const Result before = RunCli(list, true);
  ASSERT_EQ(before.exit_code, 0) << before.output;
  EXPECT_EQ(before.output, "RUN\tRVES\tMIN_STEP\tMAX_STEP\ngone\t2\t0\t1\nkeep\t1\t0\t0\n");

  const Result one =
      RunCli(absl::StrCat("drop ", server.server_flag(), " --run=gone --id=5"), true);
  ASSERT_EQ(one.exit_code, 0) << one.output;
  EXPECT_EQ(one.output, absl::StrCat("dropped 1 RVEs of run gone on ", server.address(), "\n"));
  EXPECT_EQ(RunCli(list, true).output,
            "RUN\tRVES\tMIN_STEP\tMAX_STEP\ngone\t1\t0\t0\nkeep\t1\t0\t0\n");
  const Result all = RunCli(absl::StrCat("drop ", server.server_flag(), " --run=gone"), true);
  ASSERT_EQ(all.exit_code, 0) << all.output;
  EXPECT_TRUE(all.output.starts_with("dropped 1 RVEs of run gone")) << all.output;
  EXPECT_EQ(RunCli(list, true).output, "RUN\tRVES\tMIN_STEP\tMAX_STEP\nkeep\t1\t0\t0\n");

  const Result unknown = RunCli(absl::StrCat("drop ", server.server_flag(), " --run=gone"));
  EXPECT_EQ(unknown.exit_code, 1) << unknown.output;
  EXPECT_TRUE(absl::StrContains(unknown.output, "NOT_FOUND: ")) << unknown.output;
  const Result no_run = RunCli(absl::StrCat("drop ", server.server_flag()));
  EXPECT_EQ(no_run.exit_code, 2) << no_run.output;
  EXPECT_TRUE(absl::StrContains(no_run.output, "--run=RUN is required")) << no_run.output;
  EXPECT_EQ(server.Stop(), 0) << server.Log();
}

// A file of another kind says which command reads it: an mpm_client
// checkpoint is resumed, not restored; a template file is uploaded.
TEST(CliTest, RestoreOfAnotherKindOfFileSaysWhatToDo) {
  const std::string dir = TempPath("mpm_run");
  testing_util::CommandResult run = testing_util::RunCommand(
      absl::StrCat("'", MPM_CLIENT_PATH, "' run '", RVEHUB_SOURCE_DIR,
                   "/cases/single-element-biaxial.json' --out='", dir, "' --template-cache='",
                   TempPath("templates"), "' --stop-after=1 --quiet --threads=1 2>&1"));
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const std::string checkpoint = dir + "/checkpoint.h5";
  const Result restore =
      RunCli(absl::StrCat("restore --server=127.0.0.1:1 --file='", checkpoint, "'"));
  EXPECT_EQ(restore.exit_code, 1) << restore.output;
  EXPECT_TRUE(
      absl::StrContains(restore.output, absl::StrCat(checkpoint, " is an mpm_client checkpoint")))
      << restore.output;
  EXPECT_TRUE(
      absl::StrContains(restore.output, absl::StrCat("`mpm_client resume ", checkpoint, "`")))
      << restore.output;
  EXPECT_FALSE(absl::StrContains(restore.output, "ReadSimCheckpoint")) << restore.output;
  const Result upload =
      RunCli(absl::StrCat("upload-template --server=127.0.0.1:1 --file='", checkpoint, "'"));
  EXPECT_EQ(upload.exit_code, 1) << upload.output;
  EXPECT_TRUE(absl::StrContains(upload.output, "`mpm_client resume ")) << upload.output;

  const std::string templates = TempPath("templates") + "/SET-dense-seed1.h5";
  const Result restore_template =
      RunCli(absl::StrCat("restore --server=127.0.0.1:1 --file='", templates, "'"));
  EXPECT_EQ(restore_template.exit_code, 1) << restore_template.output;
  EXPECT_TRUE(absl::StrContains(restore_template.output,
                                absl::StrCat("`rve_cli upload-template --file=", templates, "`")))
      << restore_template.output;
  std::filesystem::remove_all(dir);
  std::filesystem::remove_all(TempPath("templates"));
}

TEST(CliServerTest, GetPrintsOneRve) {
  Server server;
  ASSERT_FALSE(server.address().empty());
  const std::string name = PrepareAndUpload(server, 2);
  CreateRves(server, "g", name, {5, 6});
  const v1::ApplyResponse applied = Compress(server, "g", 1, {5});
  ASSERT_EQ(applied.results_size(), 1);
  const v1::RveState& state = applied.results(0).state();

  const std::string get = absl::StrCat("get ", server.server_flag(), " --run=g --id=5");
  const Result text = RunCli(get, true);
  ASSERT_EQ(text.exit_code, 0) << text.output;
  for (const char* key : {"run ", "id ", "step ", "stress_Pa (tension +) ", "p_Pa", "q_Pa",
                          "void_ratio ", "porosity ", "coordination ", "mechanical_coordination ",
                          "contacts ", "fabric ", "Fa ", "permeability_m_per_s ", "F "}) {
    EXPECT_TRUE(absl::StrContains(text.output, absl::StrCat("\n", key)) ||
                text.output.starts_with(key))
        << "no " << key << " in\n"
        << text.output;
  }
  EXPECT_TRUE(absl::StrContains(text.output, "\nstep                       1\n")) << text.output;
  EXPECT_FALSE(absl::StrContains(text.output, "tangent")) << text.output;
  const Result with_tangent = RunCli(absl::StrCat(get, " --tangent"), true);
  ASSERT_EQ(with_tangent.exit_code, 0) << with_tangent.output;
  EXPECT_TRUE(absl::StrContains(with_tangent.output, "\ntangent_Pa ")) << with_tangent.output;
  EXPECT_EQ(std::count(with_tangent.output.begin(), with_tangent.output.end(), '\n'),
            std::count(text.output.begin(), text.output.end(), '\n') + 10);

  const Result json = RunCli(absl::StrCat(get, " --format=json --tangent"), true);
  ASSERT_EQ(json.exit_code, 0) << json.output;
  EXPECT_EQ(std::count(json.output.begin(), json.output.end(), '\n'), 1);
  const nlohmann::json j = nlohmann::json::parse(json.output, nullptr, /*allow_exceptions=*/false);
  ASSERT_TRUE(j.is_object()) << json.output;
  // The rvehub.v1 RveState field order, run and id first.
  EXPECT_TRUE(json.output.starts_with("{\"run_id\":\"g\",\"id\":5,\"step\":1,")) << json.output;
  EXPECT_EQ(j["run_id"], "g");
  EXPECT_EQ(j["id"], 5);
  EXPECT_EQ(j["step"], 1);
  // The numbers are the server's, bit for bit.
  for (const auto& [key, value] :
       {std::pair<const char*, double>{"mean_pressure", state.mean_pressure()},
        {"deviator_stress", state.deviator_stress()},
        {"void_ratio", state.void_ratio()},
        {"coordination", state.coordination()},
        {"permeability", state.permeability()},
        {"fabric_anisotropy", state.fabric_anisotropy()}}) {
    ASSERT_TRUE(j[key].is_number()) << key;
    const double got = j[key].get<double>();
    EXPECT_EQ(std::memcmp(&got, &value, sizeof(double)), 0)
        << key << ": " << got << " vs " << value;
  }
  ASSERT_EQ(j["stress"].size(), 3u);
  const double sxx = j["stress"][0][0].get<double>();
  const double expected_sxx = state.stress(0);
  EXPECT_EQ(std::memcmp(&sxx, &expected_sxx, sizeof(double)), 0);
  ASSERT_EQ(j["tangent"].size(), 9u);
  EXPECT_EQ(j["tangent"][8].size(), 9u);
  const Result json_step0 =
      RunCli(absl::StrCat("get ", server.server_flag(), " --run=g --id=6 --format=json"), true);
  ASSERT_EQ(json_step0.exit_code, 0) << json_step0.output;
  const nlohmann::json j0 = nlohmann::json::parse(json_step0.output, nullptr, false);
  EXPECT_EQ(j0["step"], 0) << json_step0.output;
  EXPECT_FALSE(j0.contains("tangent")) << json_step0.output;

  const Result unknown_run = RunCli(absl::StrCat("get ", server.server_flag(), " --run=x --id=5"));
  EXPECT_EQ(unknown_run.exit_code, 1) << unknown_run.output;
  EXPECT_TRUE(absl::StrContains(
      unknown_run.output,
      absl::StrCat("NOT_FOUND: RVE server ", server.address(), ": unknown run \"x\"")))
      << unknown_run.output;
  const Result unknown_id = RunCli(absl::StrCat("get ", server.server_flag(), " --run=g --id=99"));
  EXPECT_EQ(unknown_id.exit_code, 1) << unknown_id.output;
  EXPECT_TRUE(absl::StrContains(unknown_id.output, "NOT_FOUND: ")) << unknown_id.output;
  EXPECT_TRUE(absl::StrContains(unknown_id.output, "99")) << unknown_id.output;
  EXPECT_EQ(server.Stop(), 0) << server.Log();
}

// checkpoint from one server, restore into another (whose small message
// limit makes the import take several chunks); the restored RVEs are the
// exported ones bit for bit and continue identically.
TEST(CliServerTest, CheckpointAndRestoreRoundTrip) {
  Server source;
  Server target({"--max-message-mb=1"});
  ASSERT_FALSE(source.address().empty());
  ASSERT_FALSE(target.address().empty());
  const std::string name = PrepareAndUpload(source, 2);
  std::vector<std::int64_t> ids_a;
  for (std::int64_t id = 1; id <= 24; ++id) ids_a.push_back(id * 10);
  const std::vector<std::int64_t> ids_b = {7, 8};
  CreateRves(source, "a", name, ids_a);
  CreateRves(source, "b", name, ids_b);
  Compress(source, "a", 1, ids_a);

  const Result info = RunCli(absl::StrCat("info ", source.server_flag()), true);
  EXPECT_TRUE(absl::StrContains(info.output, "RVEs       26 of at most")) << info.output;
  EXPECT_TRUE(absl::StrContains(info.output, "runs: 2\n")) << info.output;
  EXPECT_TRUE(absl::StrContains(info.output, "  a           24  1\n")) << info.output;
  EXPECT_TRUE(absl::StrContains(info.output, "  b            2  0\n")) << info.output;

  const std::string all = TempPath("all.h5"), only_b = TempPath("b.h5");
  const Result saved =
      RunCli(absl::StrCat("checkpoint ", source.server_flag(), " --out='", all, "'"));
  ASSERT_EQ(saved.exit_code, 0) << saved.output;
  EXPECT_TRUE(absl::StrContains(saved.output, "wrote 26 RVEs of 2 runs")) << saved.output;
  EXPECT_TRUE(absl::StrContains(saved.output, " bytes, ")) << saved.output;
  const Result saved_b =
      RunCli(absl::StrCat("checkpoint ", source.server_flag(), " --run=b --out='", only_b, "'"));
  ASSERT_EQ(saved_b.exit_code, 0) << saved_b.output;
  EXPECT_TRUE(absl::StrContains(saved_b.output, "wrote 2 RVEs of 1 runs")) << saved_b.output;
  const Result missing_run =
      RunCli(absl::StrCat("checkpoint ", source.server_flag(), " --run=x --out='", only_b, "'"));
  EXPECT_EQ(missing_run.exit_code, 1) << missing_run.output;
  EXPECT_TRUE(absl::StrContains(
      missing_run.output,
      absl::StrCat("NOT_FOUND: RVE server ", source.address(), ": unknown run \"x\"")))
      << missing_run.output;

  const std::string restore = absl::StrCat("restore ", target.server_flag(), " --file='", all, "'");
  const Result restored_a = RunCli(absl::StrCat(restore, " --run=a"));
  ASSERT_EQ(restored_a.exit_code, 0) << restored_a.output;
  EXPECT_TRUE(absl::StrContains(restored_a.output, "imported 24 RVEs")) << restored_a.output;
  EXPECT_FALSE(absl::StrContains(restored_a.output, "(1 chunks")) << restored_a.output;
  // All or nothing: run a is there already, so b is not imported either.
  const Result twice = RunCli(restore);
  EXPECT_EQ(twice.exit_code, 1) << twice.output;
  EXPECT_TRUE(absl::StrContains(twice.output, "ALREADY_EXISTS: ")) << twice.output;
  const Result none = RunCli(absl::StrCat(restore, " --run=zzz"));
  EXPECT_EQ(none.exit_code, 1) << none.output;
  EXPECT_TRUE(absl::StrContains(none.output, "NOT_FOUND: ")) << none.output;
  const Result restored_b =
      RunCli(absl::StrCat("restore ", target.server_flag(), " --file='", only_b, "'"));
  EXPECT_EQ(restored_b.exit_code, 0) << restored_b.output;
  EXPECT_TRUE(absl::StrContains(restored_b.output, "imported 2 RVEs")) << restored_b.output;
  const Result wrong_kind = RunCli(
      absl::StrCat("restore ", target.server_flag(), " --file='", TempPath("nonexistent.h5"), "'"));
  EXPECT_EQ(wrong_kind.exit_code, 1) << wrong_kind.output;
  const Result from_target =
      RunCli(absl::StrCat("checkpoint ", target.server_flag(), " --out='", all, "'"));
  EXPECT_EQ(from_target.exit_code, 0) << from_target.output;
  std::remove(all.c_str());
  std::remove(only_b.c_str());

  EXPECT_EQ(ExportRun(target, "a", ids_a), ExportRun(source, "a", ids_a));
  EXPECT_EQ(ExportRun(target, "b", ids_b), ExportRun(source, "b", ids_b));
  const v1::ApplyResponse next_source = Compress(source, "a", 2, ids_a);
  const v1::ApplyResponse next_target = Compress(target, "a", 2, ids_a);
  ASSERT_EQ(next_source.results_size(), next_target.results_size());
  for (int k = 0; k < next_source.results_size(); ++k) {
    // Everything but the engine's time (a measurement, not a result).
    v1::RveResult a = next_source.results(k), b = next_target.results(k);
    a.clear_engine_seconds();
    b.clear_engine_seconds();
    EXPECT_EQ(a.SerializeAsString(), b.SerializeAsString()) << "id " << ids_a[k];
  }
  EXPECT_EQ(source.Stop(), 0) << source.Log();
  EXPECT_EQ(target.Stop(), 0) << target.Log();
}

TEST(CliServerTest, TokenFromTheTokenFile) {
  const std::string token_file = TempPath("token");
  std::ofstream(token_file) << "  s3cret-token\n";
  Server server({absl::StrCat("--auth-token-file=", token_file)});
  ASSERT_FALSE(server.address().empty());
  const Result refused = RunCli(absl::StrCat("info ", server.server_flag()));
  EXPECT_EQ(refused.exit_code, 1) << refused.output;
  EXPECT_TRUE(absl::StrContains(refused.output, "UNAUTHENTICATED: ")) << refused.output;
  const Result accepted =
      RunCli(absl::StrCat("info ", server.server_flag(), " --token-file='", token_file, "'"));
  EXPECT_EQ(accepted.exit_code, 0) << accepted.output;
  EXPECT_TRUE(absl::StrContains(accepted.output, "authentication on")) << accepted.output;
  const Result no_file = RunCli(
      absl::StrCat("info ", server.server_flag(), " --token-file='", TempPath("no_token"), "'"));
  EXPECT_EQ(no_file.exit_code, 1) << no_file.output;
  EXPECT_TRUE(absl::StrContains(no_file.output, "NOT_FOUND: ")) << no_file.output;
  std::remove(token_file.c_str());
  EXPECT_EQ(server.Stop(), 0) << server.Log();
}

// rve_cli checks --name on the client side (client::ValidateName, so that a
// bad name fails before the preparation): the server's rule and messages.
TEST(CliTest, ClientNameCheckIsTheServers) {
  for (const std::string& name :
       {std::string("SET-dense-seed1"), std::string("._-"), std::string(), std::string(128, 'a'),
        std::string(129, 'a'), std::string("a/b"), std::string("a b"), std::string("\xc3\xbc")}) {
    EXPECT_EQ(client::ValidateName("--name", name), service::ValidateName("--name", name))
        << "'" << name << "'";
  }
}

// RemoteServer, rve_cli's way to a server: plain results, and errors that
// keep the server's code and name the server.
TEST(CliServerTest, RemoteServerNamesTheServerInErrors) {
  Server server;
  ASSERT_FALSE(server.address().empty());
  absl::StatusOr<std::unique_ptr<client::RemoteServer>> c =
      client::RemoteServer::Connect(server.address(), {});
  ASSERT_TRUE(c.ok()) << c.status();
  const absl::StatusOr<client::ServerInfo> info = (*c)->GetServerInfo();
  ASSERT_TRUE(info.ok()) << info.status();
  EXPECT_EQ(info->api_version, "rvehub.v1");
  const absl::StatusOr<std::vector<RunInfo>> runs = (*c)->ListRuns();
  ASSERT_TRUE(runs.ok()) << runs.status();
  EXPECT_TRUE(runs->empty());
  const std::int64_t ids[] = {1};
  const absl::StatusOr<std::int64_t> dropped = (*c)->DropRves("none", ids);
  EXPECT_TRUE(absl::IsNotFound(dropped.status())) << dropped.status();
  EXPECT_TRUE(absl::StartsWith(dropped.status().message(),
                               absl::StrCat("RVE server ", server.address(), ": ")))
      << dropped.status();
  c->reset();
  EXPECT_EQ(server.Stop(), 0) << server.Log();
}

}  // namespace
}  // namespace rvehub::cli
