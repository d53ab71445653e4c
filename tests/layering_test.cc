// The layers point one way, folder by folder: values and common at the
// bottom; the engine, the store and the wire on them; the service on those;
// the client library on values and the wire alone; the embedded endpoint on
// the client's interface and the service; the binaries and clients on top.
// This test reads every source file's #include lines and fails, naming file,
// line and header, when one reaches across the order (tests/ and bench/ may
// include anything).
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "gtest/gtest.h"

namespace rvehub {
namespace {

namespace fs = std::filesystem;

struct Layer {
  std::string folder;  // relative to the source root
  // Project headers ("a/b.h") it may include, by folder prefix.
  std::vector<std::string> may_include;
  // System headers (<a/b.h>) it may include besides the C++ and C standard
  // library: by prefix.
  std::vector<std::string> may_include_system;
  bool standard_io = true;  // <fstream>, <sys/...>, <unistd.h> and the like
};

// The C++ standard library and POSIX C headers: a name without a slash and
// no ".h", or one of the few C headers the layers use.
bool IsStandard(const std::string& header, bool io) {
  if (header.find('/') == std::string::npos && !absl::EndsWith(header, ".h")) {
    return io || (header != "fstream" && header != "iostream" && header != "filesystem" &&
                  header != "cstdio");
  }
  if (!io) return false;
  for (const char* c : {"unistd.h", "fcntl.h", "signal.h", "sys/", "netdb.h", "arpa/", "netinet/",
                        "poll.h", "errno.h", "time.h"}) {
    if (absl::StartsWith(header, c)) return true;
  }
  return false;
}

// Each folder may include its own headers and those of the folders listed,
// by prefix: no file-level exceptions. The order, bottom up (README.md, Tour):
// values, common <- engine, store, wire <- service <- client <- embedded <-
// the binaries and clients.
const std::vector<Layer>& Layers() {
  static const auto* layers = new std::vector<Layer>{
      // The values every layer shares: plain types, their ranges and checks.
      {"rve_server/values", {"rve_server/values/", "absl/"}, {"Eigen/"}, /*standard_io=*/false},
      // What every binary shares: Abseil and the standard library (the
      // long-running binaries' heap settings: glibc's malloc.h; Eigen for the
      // elasticity formulas the clients' stand-in materials share).
      {"rve_server/common", {"rve_server/common/", "absl/"}, {"malloc.h", "Eigen/"}},
      // The engine: Eigen, Abseil, the standard library; no I/O.
      {"rve_server/engine",
       {"rve_server/engine/", "rve_server/values/", "rve_server/common/", "absl/"},
       {"Eigen/"},
       /*standard_io=*/false},
      {"store",
       {"store/", "rve_server/values/", "rve_server/common/", "absl/"},
       {"hdf5.h", "Eigen/"}},
      {"rve_server/wire",
       {"rve_server/wire/", "rve_server/values/", "rve_server/common/", "rvehub/v1/", "absl/"},
       {"Eigen/", "google/protobuf/"}},
      {"rve_server/service",
       {"rve_server/service/", "rve_server/engine/", "rve_server/values/", "rve_server/wire/",
        "rve_server/common/", "store/", "rvehub/v1/", "absl/"},
       {"grpcpp/", "grpc/", "Eigen/", "google/protobuf/"}},
      {"rve_server/server",
       {"rve_server/server/", "rve_server/service/", "rve_server/common/", "absl/"},
       {"grpcpp/"}},
      // The client library: values and the wire only.
      {"rve_server/client",
       {"rve_server/client/", "rve_server/values/", "rve_server/wire/", "rve_server/common/",
        "rvehub/v1/", "absl/"},
       {"grpcpp/", "grpc/", "Eigen/", "google/protobuf/"}},
      // The service in a client's process, behind the client's interface.
      {"rve_server/embedded",
       {"rve_server/embedded/", "rve_server/client/", "rve_server/service/", "rve_server/engine/",
        "rve_server/values/", "rve_server/common/", "absl/"},
       {"Eigen/"}},
      // What the client programs share: plots (cairo), JSON input files read
      // into plain structs (field tables). No client's model.
      {"toolkit", {"toolkit/", "rve_server/common/", "absl/"}, {"cairo", "Eigen/", "nlohmann/"}},
      {"rve_server/cli",
       {"rve_server/cli/", "rve_server/client/", "rve_server/embedded/", "rve_server/values/",
        "rve_server/common/", "store/", "toolkit/", "absl/", "nlohmann/"},
       {"Eigen/", "nlohmann/"}},
      // What the continuum clients' cases hold alike, as plain data: the
      // standard library only, so an RVE-free core may hold it.
      {"client_case/spec", {"client_case/spec/"}, {}, /*standard_io=*/false},
      // The case sections every continuum client reads alike (templates, rve)
      // and --set overrides: field tables over the values' parameter sets; no
      // client's own model.
      {"client_case",
       {"client_case/", "toolkit/", "rve_server/values/", "rve_server/common/", "absl/",
        "nlohmann/"},
       {"Eigen/", "nlohmann/"}},
      // What the continuum clients' run layers share: the case templates
      // (prepared on the embedded packings, cached in the store), the RVE
      // endpoints, timeseries.csv, summary.json, run.json and the time split.
      // No client's own model or case reader.
      {"client_run",
       {"client_run/", "client_case/spec/", "rve_server/client/", "rve_server/embedded/",
        "rve_server/values/", "rve_server/common/", "store/", "absl/", "nlohmann/"},
       {"Eigen/", "nlohmann/"}},
      // The RVE-free MPM: neither engine nor store nor client.
      {"mpm_client/core",
       {"mpm_client/core/", "client_case/spec/", "rve_server/common/", "absl/"},
       {"Eigen/"}},
      {"mpm_client/case",
       {"mpm_client/case/", "mpm_client/core/", "client_case/", "toolkit/", "rve_server/values/",
        "rve_server/common/", "absl/", "nlohmann/"},
       {"Eigen/", "nlohmann/"}},
      {"mpm_client/run",
       {"mpm_client/run/", "mpm_client/case/", "mpm_client/core/", "client_run/",
        "rve_server/client/", "rve_server/embedded/", "rve_server/values/", "rve_server/common/",
        "store/", "toolkit/", "absl/", "nlohmann/"},
       {"Eigen/", "nlohmann/"}},
      // The binary (rvehub/version.h: the build's git describe, generated).
      {"mpm_client",
       {"mpm_client/", "client_run/", "rve_server/client/", "rve_server/common/", "absl/",
        "nlohmann/", "rvehub/version.h"},
       {"Eigen/", "nlohmann/"}},
      // fem_client's case files: the shared sections, never mpm_client's.
      {"fem_client/case",
       {"fem_client/case/", "fem_client/core/", "client_case/", "toolkit/", "rve_server/values/",
        "rve_server/common/", "absl/", "nlohmann/"},
       {"Eigen/", "nlohmann/"}},
      // The RVE-free FEM: neither engine nor store nor client, and no I/O.
      {"fem_client/core",
       {"fem_client/core/", "rve_server/common/", "absl/"},
       {"Eigen/"},
       /*standard_io=*/false},
      // Running an FEM case on RVEs: the core, the case, the client library
      // (the RVE pool), the embedded endpoint, the store, the client
      // programs' toolkit and the clients' shared run layer.
      {"fem_client/run",
       {"fem_client/run/", "fem_client/case/", "fem_client/core/", "client_case/", "client_run/",
        "rve_server/client/", "rve_server/embedded/", "rve_server/values/", "rve_server/common/",
        "store/", "toolkit/", "absl/", "nlohmann/"},
       {"Eigen/", "nlohmann/"}},
      // The binary: commands and flags over the run layer.
      {"fem_client",
       {"fem_client/", "client_run/", "rve_server/client/", "rve_server/common/", "absl/",
        "nlohmann/", "rvehub/version.h"},
       {"Eigen/", "nlohmann/"}},
  };
  return *layers;
}

// The layer a source file (path relative to the root) belongs to: the one
// with the longest folder holding it (mpm_client/core/ before mpm_client/);
// nullptr when none does.
const Layer* LayerOf(const std::string& file) {
  const Layer* best = nullptr;
  for (const Layer& layer : Layers()) {
    if (absl::StartsWith(file, layer.folder + "/") &&
        (best == nullptr || layer.folder.size() > best->folder.size())) {
      best = &layer;
    }
  }
  return best;
}

bool IsSource(const fs::directory_entry& entry) {
  const std::string ext = entry.path().extension().string();
  return entry.is_regular_file() && (ext == ".h" || ext == ".cc");
}

// Every source file of the product's folders has a rule: a new folder
// cannot slip past the order.
TEST(LayeringTest, EveryFolderHasALayer) {
  const fs::path root(RVEHUB_SOURCE_DIR);
  for (const char* top : {"rve_server", "store", "toolkit", "client_case", "client_run",
                          "mpm_client", "fem_client"}) {
    for (const fs::directory_entry& entry : fs::recursive_directory_iterator(root / top)) {
      if (!IsSource(entry)) continue;
      const std::string name = fs::relative(entry.path(), root).string();
      EXPECT_NE(LayerOf(name), nullptr) << name << " is in no layer of layering_test.cc";
    }
  }
}

TEST(LayeringTest, IncludesFollowTheLayerOrder) {
  const fs::path root(RVEHUB_SOURCE_DIR);
  const std::regex include_line(R"re(^\s*#\s*include\s*([<"])([^>"]+)[>"])re");
  int files = 0;
  for (const Layer& layer : Layers()) {
    ASSERT_TRUE(fs::is_directory(root / layer.folder)) << layer.folder;
    for (const fs::directory_entry& entry : fs::recursive_directory_iterator(root / layer.folder)) {
      if (!IsSource(entry)) continue;
      const std::string name = fs::relative(entry.path(), root).string();
      if (LayerOf(name) != &layer) continue;  // a sub-folder's own layer checks it
      ++files;
      std::ifstream in(entry.path());
      std::string line;
      for (int number = 1; std::getline(in, line); ++number) {
        std::smatch m;
        if (!std::regex_search(line, m, include_line)) continue;
        const std::string header = m[2];
        bool ok = false;
        if (m[1] == "\"") {
          for (const std::string& prefix : layer.may_include) {
            ok = ok || absl::StartsWith(header, prefix);
          }
        } else {
          ok = IsStandard(header, layer.standard_io);
          for (const std::string& prefix : layer.may_include_system) {
            ok = ok || absl::StartsWith(header, prefix);
          }
        }
        EXPECT_TRUE(ok) << name << ":" << number << " includes " << header << ", which "
                        << layer.folder << " may not (layer order: README.md, Tour)";
      }
    }
  }
  EXPECT_GT(files, 50) << "too few files found under " << root;
}

// The rule itself must catch what it is meant to: a mpm_client file that
// includes the server's service or rve_cli's folder, an engine file with
// I/O or gRPC.
TEST(LayeringTest, TheRulesRejectCrossings) {
  const auto allowed = [](const std::string& folder, const std::string& header, bool quoted) {
    for (const Layer& layer : Layers()) {
      if (layer.folder != folder) continue;
      bool ok = quoted ? false : IsStandard(header, layer.standard_io);
      for (const std::string& p : quoted ? layer.may_include : layer.may_include_system) {
        ok = ok || absl::StartsWith(header, p);
      }
      return ok;
    }
    return false;
  };
  EXPECT_FALSE(allowed("mpm_client", "rve_server/service/registry.h", true));
  EXPECT_FALSE(allowed("mpm_client/run", "rve_server/service/registry.h", true));
  EXPECT_FALSE(allowed("mpm_client", "rve_server/engine/rve.h", true));
  EXPECT_FALSE(allowed("mpm_client", "rve_server/cli/element_test_io.h", true));
  EXPECT_FALSE(allowed("store", "rve_server/engine/rve.h", true));
  EXPECT_FALSE(allowed("store", "rve_server/service/registry.h", true));
  EXPECT_FALSE(allowed("store", "rve_server/client/endpoint.h", true));
  EXPECT_FALSE(allowed("rve_server/values", "rve_server/engine/rve.h", true));
  EXPECT_FALSE(allowed("rve_server/values", "fstream", false));
  EXPECT_FALSE(allowed("rve_server/engine", "store/checkpoint.h", true));
  EXPECT_FALSE(allowed("rve_server/engine", "fstream", false));
  EXPECT_FALSE(allowed("rve_server/engine", "grpcpp/grpcpp.h", false));
  EXPECT_FALSE(allowed("rve_server/service", "rve_server/client/endpoint.h", true));
  EXPECT_FALSE(allowed("rve_server/client", "rve_server/service/registry.h", true));
  EXPECT_FALSE(allowed("rve_server/client", "rve_server/engine/rve.h", true));
  EXPECT_FALSE(allowed("rve_server/client", "store/checkpoint.h", true));
  EXPECT_FALSE(allowed("rve_server/common", "cairo.h", false));
  EXPECT_FALSE(allowed("rve_server/server", "toolkit/plot.h", true));
  EXPECT_FALSE(allowed("toolkit", "mpm_client/core/model.h", true));
  EXPECT_FALSE(allowed("toolkit", "rve_server/client/endpoint.h", true));
  EXPECT_TRUE(allowed("rve_server/engine", "Eigen/Dense", false));
  EXPECT_TRUE(allowed("rve_server/engine", "vector", false));
  EXPECT_TRUE(allowed("rve_server/client", "rve_server/wire/convert.h", true));
  EXPECT_TRUE(allowed("rve_server/embedded", "rve_server/service/registry.h", true));
  EXPECT_TRUE(allowed("mpm_client/run", "rve_server/client/endpoint.h", true));
  EXPECT_FALSE(allowed("mpm_client/core", "rve_server/values/state.h", true));
  EXPECT_FALSE(allowed("mpm_client/core", "store/results.h", true));
  EXPECT_FALSE(allowed("mpm_client/core", "rve_server/client/rve_pool.h", true));
  EXPECT_FALSE(allowed("mpm_client/case", "mpm_client/run/simulation.h", true));
  EXPECT_FALSE(allowed("mpm_client/run", "rve_server/engine/rve.h", true));
  EXPECT_EQ(LayerOf("mpm_client/core/solver.h")->folder, "mpm_client/core");
  EXPECT_EQ(LayerOf("mpm_client/mpm_client_main.cc")->folder, "mpm_client");
  EXPECT_EQ(LayerOf("bench/bench_dem.cc"), nullptr);
  EXPECT_TRUE(allowed("mpm_client/case", "toolkit/field_table.h", true));
  EXPECT_FALSE(allowed("fem_client/core", "rve_server/client/endpoint.h", true));
  EXPECT_FALSE(allowed("fem_client/core", "rve_server/engine/rve.h", true));
  EXPECT_FALSE(allowed("fem_client/core", "store/results.h", true));
  EXPECT_FALSE(allowed("fem_client/core", "mpm_client/core/elastic.h", true));
  EXPECT_FALSE(allowed("fem_client/core", "fstream", false));
  EXPECT_TRUE(allowed("fem_client/core", "Eigen/Sparse", false));
  EXPECT_EQ(LayerOf("fem_client/core/static_solver.h")->folder, "fem_client/core");
  // The shared case sections serve both clients and depend on neither; the
  // clients' case readers do not reach into each other.
  EXPECT_TRUE(allowed("mpm_client/case", "client_case/sections.h", true));
  EXPECT_TRUE(allowed("fem_client/case", "client_case/sections.h", true));
  EXPECT_TRUE(allowed("mpm_client/core", "client_case/spec/rve_spec.h", true));
  EXPECT_FALSE(allowed("mpm_client/core", "client_case/sections.h", true));
  EXPECT_FALSE(allowed("client_case", "mpm_client/core/model.h", true));
  EXPECT_FALSE(allowed("client_case", "fem_client/case/fem_case.h", true));
  EXPECT_FALSE(allowed("client_case", "rve_server/client/endpoint.h", true));
  EXPECT_FALSE(allowed("client_case/spec", "rve_server/values/material.h", true));
  EXPECT_FALSE(allowed("client_case/spec", "Eigen/Dense", false));
  EXPECT_FALSE(allowed("fem_client/case", "mpm_client/case/case.h", true));
  EXPECT_FALSE(allowed("fem_client/case", "mpm_client/core/model.h", true));
  EXPECT_FALSE(allowed("mpm_client/case", "fem_client/case/case.h", true));
  EXPECT_EQ(LayerOf("client_case/spec/rve_spec.h")->folder, "client_case/spec");
  EXPECT_EQ(LayerOf("fem_client/case/case.cc")->folder, "fem_client/case");
  // The clients' shared run layer serves both and depends on neither; the
  // clients' run layers do not reach into each other.
  EXPECT_TRUE(allowed("mpm_client/run", "client_run/templates.h", true));
  EXPECT_TRUE(allowed("fem_client/run", "client_run/templates.h", true));
  EXPECT_TRUE(allowed("client_run", "store/checkpoint.h", true));
  EXPECT_TRUE(allowed("client_run", "rve_server/embedded/packings.h", true));
  EXPECT_FALSE(allowed("client_run", "mpm_client/core/model.h", true));
  EXPECT_FALSE(allowed("client_run", "fem_client/core/mesh.h", true));
  EXPECT_FALSE(allowed("client_run", "client_case/sections.h", true));
  EXPECT_FALSE(allowed("client_run", "rve_server/service/registry.h", true));
  EXPECT_FALSE(allowed("client_run", "rve_server/engine/rve.h", true));
  EXPECT_FALSE(allowed("fem_client/run", "mpm_client/run/output.h", true));
  EXPECT_FALSE(allowed("mpm_client/run", "fem_client/run/simulation.h", true));
  EXPECT_EQ(LayerOf("fem_client/run/simulation.cc")->folder, "fem_client/run");
  EXPECT_TRUE(allowed("fem_client", "client_run/run_record.h", true));
  EXPECT_FALSE(allowed("fem_client", "rve_server/engine/rve.h", true));
  EXPECT_FALSE(allowed("fem_client", "rve_server/embedded/endpoint.h", true));
  EXPECT_FALSE(allowed("fem_client", "mpm_client/run/simulation.h", true));
  EXPECT_EQ(LayerOf("fem_client/fem_client_main.cc")->folder, "fem_client");
  EXPECT_EQ(LayerOf("client_run/templates.cc")->folder, "client_run");
}

}  // namespace
}  // namespace rvehub
