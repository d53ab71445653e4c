// rve_cli's server commands against real rve_server processes on free loopback
// ports: templates, an element test on the server bit-identical to the local
// one, listing and dropping runs, get, checkpoint and restore, tokens.
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
#include "tests/rve_server/cli/cli_test_util.h"
#include "tests/support/process_util.h"

namespace rvehub::cli::cli_test {
namespace {

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
}  // namespace rvehub::cli::cli_test
