// The rve_cli tool (rve_server/cli/rve_cli.cc), run as a subprocess: usage,
// exit codes and error messages, one short oedometer run whose CSV and PNG
// outputs are checked, and template preparation.
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
#include "rve_server/embedded/packings.h"
#include "rve_server/service/registry.h"
#include "rvehub/v1/rve_service.grpc.pb.h"
#include "store/checkpoint.h"
#include "tests/rve_server/cli/cli_test_util.h"
#include "tests/support/process_util.h"

namespace rvehub::cli::cli_test {
namespace {

const char* const kCommands[] = {"element-test", "prepare",         "materials",  "info",
                                 "get",          "upload-template", "checkpoint", "contacts",
                                 "restore",      "list-runs",       "drop"};
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
// contacts: one RVE of an RVE file as discs and contact forces. The forces
// are the engine's: their Love–Weber sum −(1/V) Σ f_j ⊗ b over the file's
// contacts is the stress the packing reports, to round-off.
TEST(CliTest, ContactsWritesTheDiscsAndForcesOfOneRve) {
  absl::StatusOr<std::vector<TemplateRecord>> templates =
      store::ReadTemplates(RVEHUB_SOURCE_DIR "/cases/reference/hexagonal-400.h5");
  ASSERT_TRUE(templates.ok()) << templates.status();
  RveRecord rve;
  rve.run_id = "chains";
  rve.id = 7;
  rve.packing = templates->front().packing;
  const std::string file = TempPath("contacts-rves.h5"), prefix = TempPath("contacts-7");
  ASSERT_TRUE(store::WriteRves(file, std::vector<RveRecord>{rve}, {}).ok());
  const Result r = RunCli(absl::StrCat("contacts --file='", file, "' --id=7 --out='", prefix, "'"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(absl::StrContains(r.output, "RVE 7 of run \"chains\"")) << r.output;

  absl::StatusOr<embedded::PackingForces> forces = embedded::ContactForces(rve.packing);
  ASSERT_TRUE(forces.ok()) << forces.status();
  const auto lines = [](const std::string& path) {
    std::ifstream in(path);
    std::string line;
    std::size_t n = 0;
    while (std::getline(in, line)) ++n;
    return n;
  };
  EXPECT_EQ(lines(prefix + "-discs.csv"), 1 + rve.packing.radius.size());
  EXPECT_EQ(lines(prefix + "-contacts.csv"), 1 + forces->contacts.size());
  ASSERT_GT(forces->contacts.size(), 1000u);  // 400 discs of coordination 6
  Eigen::Matrix2d sum = Eigen::Matrix2d::Zero();
  for (const embedded::PackingContact& c : forces->contacts) {
    const Eigen::Vector2d n = c.branch.normalized(), t(-n.y(), n.x());
    const Eigen::Vector2d on_j = c.normal_force * n - c.tangential_force * t;
    sum -= on_j * c.branch.transpose();
  }
  const Eigen::Matrix2d stress =
      0.5 * (sum + sum.transpose()) / (forces->cell.determinant() * rve.packing.material.thickness);
  absl::StatusOr<dem::RveState> state = embedded::Observe(rve.packing, false);
  ASSERT_TRUE(state.ok()) << state.status();
  EXPECT_LT((stress - state->stress.topLeftCorner<2, 2>()).norm(), 1e-9 * state->stress.norm());
  for (const Eigen::Vector2d& x : forces->position) {
    const Eigen::Vector2d s = forces->cell.inverse() * x;
    EXPECT_TRUE(s.minCoeff() >= -1e-12 && s.maxCoeff() < 1 + 1e-12) << x.transpose();
  }

  const Result missing =
      RunCli(absl::StrCat("contacts --file='", file, "' --id=8 --out='", prefix, "'"));
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_TRUE(absl::StrContains(missing.output, "holds no RVE of id 8")) << missing.output;
  const Result negative =
      RunCli(absl::StrCat("contacts --file='", file, "' --id=-1 --out='", prefix, "'"));
  EXPECT_EQ(negative.exit_code, 2);
  EXPECT_TRUE(absl::StrContains(negative.output, "--id must be a material-point id >= 0, got -1"))
      << negative.output;
}

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

}  // namespace
}  // namespace rvehub::cli::cli_test
