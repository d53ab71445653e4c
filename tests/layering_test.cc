// The layers point one way: engine ← store ← service, and the client library
// ← mpm_client and rve_cli; toolkit (what the client programs share) ←
// mpm_client, and it knows no client. This test reads every source file's
// #include lines and fails, naming file, line and header, when one reaches
// across the order (tests/ and bench/ may include anything).
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

const std::vector<Layer>& Layers() {
  static const auto* layers = new std::vector<Layer>{
      // The engine: Eigen, Abseil, the standard library; no I/O.
      {"rve_server/engine",
       {"rve_server/engine/", "rve_server/common/status_macros.h", "absl/"},
       {"Eigen/"},
       /*standard_io=*/false},
      // What every binary shares: Abseil and the standard library (plots:
      // cairo; the long-running binaries' heap settings: glibc's malloc.h).
      {"rve_server/common", {"rve_server/common/", "absl/"}, {"cairo", "malloc.h"}},
      {"store",
       {"store/", "rve_server/engine/", "rve_server/common/", "absl/"},
       {"hdf5.h", "Eigen/"}},
      {"rve_server/service",
       {"rve_server/service/", "rve_server/engine/", "rve_server/common/", "store/", "rvehub/v1/",
        "absl/"},
       {"grpcpp/", "grpc/", "Eigen/", "google/protobuf/"}},
      {"rve_server/server",
       {"rve_server/server/", "rve_server/service/", "rve_server/common/", "absl/"},
       {"grpcpp/"}},
      // The client library: may sit on the registry (the embedded endpoint)
      // and the wire conversions, never on the server's gRPC service.
      {"rve_server/client",
       {"rve_server/client/", "rve_server/service/registry.h", "rve_server/service/rve_batch.h",
        "rve_server/service/convert.h", "rve_server/service/worker_pool.h", "rve_server/engine/",
        "rve_server/common/", "store/", "rvehub/v1/", "absl/"},
       {"grpcpp/", "grpc/", "Eigen/", "google/protobuf/"}},
      // What the client programs share (JSON input files): no client's model,
      // of the project's own headers only the Status macros.
      {"toolkit",
       {"toolkit/", "rve_server/common/status_macros.h", "absl/"},
       {"Eigen/", "nlohmann/"}},
      {"mpm_client",
       {"mpm_client/", "toolkit/", "rve_server/client/", "rve_server/engine/", "rve_server/common/",
        "store/", "absl/", "nlohmann/"},
       {"Eigen/", "nlohmann/"}},
      {"rve_server/cli",
       {"rve_server/cli/", "rve_server/client/", "rve_server/engine/", "rve_server/common/",
        "store/", "absl/", "nlohmann/"},
       {"Eigen/", "nlohmann/"}},
  };
  return *layers;
}

TEST(LayeringTest, IncludesFollowTheLayerOrder) {
  const fs::path root(RVEHUB_SOURCE_DIR);
  const std::regex include_line(R"re(^\s*#\s*include\s*([<"])([^>"]+)[>"])re");
  int files = 0;
  for (const Layer& layer : Layers()) {
    ASSERT_TRUE(fs::is_directory(root / layer.folder)) << layer.folder;
    for (const fs::directory_entry& entry : fs::recursive_directory_iterator(root / layer.folder)) {
      const std::string ext = entry.path().extension().string();
      if (!entry.is_regular_file() || (ext != ".h" && ext != ".cc")) continue;
      ++files;
      const std::string name = fs::relative(entry.path(), root).string();
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
  EXPECT_FALSE(allowed("mpm_client", "rve_server/cli/plot.h", true));
  EXPECT_FALSE(allowed("store", "rve_server/service/registry.h", true));
  EXPECT_FALSE(allowed("store", "rve_server/client/endpoint.h", true));
  EXPECT_FALSE(allowed("rve_server/engine", "store/record.h", true));
  EXPECT_FALSE(allowed("rve_server/engine", "fstream", false));
  EXPECT_FALSE(allowed("rve_server/engine", "grpcpp/grpcpp.h", false));
  EXPECT_FALSE(allowed("rve_server/service", "rve_server/client/endpoint.h", true));
  EXPECT_FALSE(allowed("toolkit", "mpm_client/model.h", true));
  EXPECT_FALSE(allowed("toolkit", "rve_server/common/text_file.h", true));
  EXPECT_TRUE(allowed("rve_server/engine", "Eigen/Dense", false));
  EXPECT_TRUE(allowed("rve_server/engine", "vector", false));
  EXPECT_TRUE(allowed("mpm_client", "rve_server/client/endpoint.h", true));
  EXPECT_TRUE(allowed("mpm_client", "toolkit/field_table.h", true));
}

}  // namespace
}  // namespace rvehub
