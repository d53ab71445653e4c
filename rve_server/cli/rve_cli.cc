// rve_cli: query single RVEs and run element tests.
//
//   rve_cli element-test --test=drained-biaxial --material=SET-dense --seed=1
//       --confining=100000 --strain=0.1 --out=biaxial.csv [--plot=biaxial.png]
//   rve_cli prepare --material=SET-dense --seed=1
//   rve_cli materials
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <iostream>
#include <string>

#include "absl/container/flat_hash_map.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "rve_server/cli/element_test_io.h"
#include "rve_server/engine/element_test.h"
#include "rve_server/engine/prepare.h"
#include "rve_server/engine/rve.h"

namespace rvehub::cli {
namespace {

constexpr char kUsage[] = R"(rve_cli — single-RVE tools of RVEHub (2-D DEM packings of discs)

Commands:
  element-test   prepare an RVE and run an element test, writing a CSV (and a PNG)
  prepare        prepare an RVE and print its initial state
  materials      list the parameter sets (shared/reference/README.md)

element-test options:
  --test=NAME        drained-biaxial | isotropic | oedometer | undrained-simple-shear |
                     cyclic-simple-shear
  --material=NAME    parameter set, e.g. SET-dense, SPFEM-biaxial, consolidation
  --seed=N           packing seed (default 1)
  --confining=PA     consolidation / lateral stress in Pa, compression + (default 100000)
  --strain=MAX       axial strain (biaxial, oedometer), volumetric strain (isotropic) or
                     shear strain (simple shear) to stop at (default 0.1)
  --out=FILE.csv     output: step,axial_strain,vol_strain,sxx,syy,sxy,p,q,void_ratio,
                     coordination,fabric_xx,fabric_yy,fabric_xy,Fa,permeability,shear_strain
                     (compression positive, Pa; strains positive in compression)
  --plot=FILE.png    optional plot of the usual curves
  --rows=N           rows recorded over the test (default 400)
  --inertial-number=I  shearing rate via I = rate·d·sqrt(rho/p) (default 1e-3)
  --cyclic-control=strain|stress  amplitude kind for cyclic-simple-shear (default strain)
  --amplitude=X      shear-strain amplitude, or shear-stress amplitude in Pa (default 0.005)
  --cycles=N         number of cycles (default 5)
)";

using Flags = absl::flat_hash_map<std::string, std::string>;

absl::StatusOr<Flags> ParseFlags(int argc, char** argv, int first,
                                 std::initializer_list<const char*> known) {
  Flags flags;
  for (int i = first; i < argc; ++i) {
    std::string arg = argv[i];
    if (!arg.starts_with("--"))
      return absl::InvalidArgumentError(absl::StrCat("unexpected argument '", arg, "'"));
    const std::size_t eq = arg.find('=');
    std::string key = arg.substr(2, eq == std::string::npos ? std::string::npos : eq - 2);
    std::string value = eq == std::string::npos ? "" : arg.substr(eq + 1);
    if (std::find_if(known.begin(), known.end(), [&](const char* k) { return key == k; }) ==
        known.end()) {
      return absl::InvalidArgumentError(absl::StrCat("unknown option --", key, " (see --help)"));
    }
    flags[key] = value;
  }
  return flags;
}

template <typename T>
absl::Status Get(const Flags& flags, const std::string& key, T* out) {
  auto it = flags.find(key);
  if (it == flags.end()) return absl::OkStatus();
  bool ok;
  if constexpr (std::is_same_v<T, double>) {
    ok = absl::SimpleAtod(it->second, out) && std::isfinite(*out);
  } else if constexpr (std::is_same_v<T, std::string>) {
    *out = it->second;
    ok = !out->empty();
  } else {
    ok = absl::SimpleAtoi(it->second, out);
  }
  if (!ok)
    return absl::InvalidArgumentError(
        absl::StrCat("bad value for --", key, ": '", it->second, "'"));
  return absl::OkStatus();
}

#define RETURN_IF_ERROR(expr)                          \
  do {                                                 \
    if (absl::Status s_ = (expr); !s_.ok()) return s_; \
  } while (false)

absl::StatusOr<dem::Packing> Prepare(const Flags& flags, std::string* name) {
  std::string material = "SET-dense";
  std::uint64_t seed = 1;
  RETURN_IF_ERROR(Get(flags, "material", &material));
  RETURN_IF_ERROR(Get(flags, "seed", &seed));
  absl::StatusOr<dem::ParameterSet> set = dem::FindParameterSet(material);
  if (!set.ok()) return set.status();
  set->preparation.seed = seed;
  *name = material;
  std::fprintf(stderr, "preparing %s (seed %llu, %d discs)...\n", material.c_str(),
               static_cast<unsigned long long>(seed), set->preparation.num_particles);
  dem::PreparationReport report;
  absl::StatusOr<dem::Packing> packing = dem::PreparePacking(
      *set, {}, &report,
      [](const std::string& line) { std::fprintf(stderr, "  %s\n", line.c_str()); });
  if (!packing.ok()) return packing.status();
  std::fprintf(
      stderr, "prepared: e0 = %.4f, p0 = %.1f Pa, Z = %.2f, compaction friction %.4f, %lld steps\n",
      report.void_ratio, report.pressure, report.coordination, report.compaction_friction,
      static_cast<long long>(report.steps));
  return packing;
}

absl::Status ElementTest(const Flags& flags) {
  dem::ElementTestSpec spec;
  std::string test = "drained-biaxial", out, plot_path, cyclic = "strain";
  RETURN_IF_ERROR(Get(flags, "test", &test));
  RETURN_IF_ERROR(Get(flags, "out", &out));
  RETURN_IF_ERROR(Get(flags, "plot", &plot_path));
  RETURN_IF_ERROR(Get(flags, "confining", &spec.confining));
  RETURN_IF_ERROR(Get(flags, "strain", &spec.max_strain));
  RETURN_IF_ERROR(Get(flags, "rows", &spec.rows));
  RETURN_IF_ERROR(Get(flags, "inertial-number", &spec.inertial_number));
  RETURN_IF_ERROR(Get(flags, "amplitude", &spec.amplitude));
  RETURN_IF_ERROR(Get(flags, "cycles", &spec.cycles));
  RETURN_IF_ERROR(Get(flags, "cyclic-control", &cyclic));
  if (out.empty()) return absl::InvalidArgumentError("--out=FILE.csv is required");
  absl::StatusOr<dem::ElementTestKind> kind = dem::ParseElementTestKind(test);
  if (!kind.ok()) return kind.status();
  spec.kind = *kind;
  if (cyclic == "strain") {
    spec.cyclic_control = dem::CyclicControl::kStrain;
  } else if (cyclic == "stress") {
    spec.cyclic_control = dem::CyclicControl::kStress;
  } else {
    return absl::InvalidArgumentError("--cyclic-control must be strain or stress");
  }
  std::string material;
  absl::StatusOr<dem::Packing> packing = Prepare(flags, &material);
  if (!packing.ok()) return packing.status();
  absl::StatusOr<dem::Rve> rve = dem::Rve::Create(*std::move(packing));
  if (!rve.ok()) return rve.status();

  const auto start = std::chrono::steady_clock::now();
  // One updating line on a terminal; a line every 10 % in a log file.
  const bool tty = isatty(fileno(stderr));
  const int every = tty ? 1 : 10;
  int last_percent = -1;
  absl::StatusOr<std::vector<dem::ElementTestRow>> rows =
      dem::RunElementTest(*rve, spec, [&](double fraction) {
        const int percent = static_cast<int>(fraction * 100) / every * every;
        if (percent == last_percent) return;
        last_percent = percent;
        const double secs =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        std::fprintf(stderr, "%s%s on %s: %3d%% (%.1f s)%s", tty ? "\r" : "", test.c_str(),
                     material.c_str(), percent, secs, tty ? "" : "\n");
        std::fflush(stderr);
      });
  if (tty) std::fprintf(stderr, "\n");
  if (!rows.ok()) return rows.status();
  RETURN_IF_ERROR(WriteElementTestCsv(out, *rows));
  std::fprintf(stderr, "wrote %zu rows to %s\n", rows->size(), out.c_str());
  if (!plot_path.empty()) {
    RETURN_IF_ERROR(WriteElementTestPlot(plot_path, spec.kind, test + " on " + material, *rows));
    std::fprintf(stderr, "wrote plot to %s\n", plot_path.c_str());
  }
  return absl::OkStatus();
}

absl::Status PrepareCommand(const Flags& flags) {
  std::string material;
  absl::StatusOr<dem::Packing> packing = Prepare(flags, &material);
  if (!packing.ok()) return packing.status();
  absl::StatusOr<dem::Rve> rve = dem::Rve::Create(*std::move(packing));
  if (!rve.ok()) return rve.status();
  const dem::RveState s = rve->Observe(/*want_tangent=*/true);
  std::printf("material %s\nparticles %d\nvoid_ratio %.6f\nporosity %.6f\n", material.c_str(),
              rve->num_particles(), s.void_ratio, s.porosity);
  std::printf("p_Pa %.3f\nsxx_Pa %.3f\nsyy_Pa %.3f\nsxy_Pa %.3f\n", s.MeanPressure(),
              -s.stress(0, 0), -s.stress(1, 1), -s.stress(0, 1));
  std::printf(
      "coordination %.4f\nmechanical_coordination %.4f\nFa %.5f\npermeability_m_per_s %.6g\n",
      s.coordination, s.mechanical_coordination, s.fabric_anisotropy, s.permeability);
  std::printf("unbalanced_force_ratio %.3g\ntime_step_s %.6g\nD_xxxx_Pa %.6g\nD_yyyy_Pa %.6g\n",
              s.unbalanced_force_ratio, s.time_step, s.tangent(0, 0), s.tangent(4, 4));
  return absl::OkStatus();
}

int Main(int argc, char** argv) {
  if (argc < 2 || std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h" ||
      std::string(argv[1]) == "help") {
    std::fputs(kUsage, argc < 2 ? stderr : stdout);
    return argc < 2 ? 2 : 0;
  }
  const std::string command = argv[1];
  for (int i = 2; i < argc; ++i) {
    if (std::string(argv[i]) == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    }
  }
  absl::Status status;
  if (command == "element-test") {
    absl::StatusOr<Flags> flags =
        ParseFlags(argc, argv, 2,
                   {"test", "material", "seed", "confining", "strain", "out", "plot", "rows",
                    "inertial-number", "cyclic-control", "amplitude", "cycles"});
    status = flags.ok() ? ElementTest(*flags) : flags.status();
  } else if (command == "prepare") {
    absl::StatusOr<Flags> flags = ParseFlags(argc, argv, 2, {"material", "seed"});
    status = flags.ok() ? PrepareCommand(*flags) : flags.status();
  } else if (command == "materials") {
    std::printf("%s\n", absl::StrJoin(dem::ParameterSetNames(), "\n").c_str());
  } else {
    status =
        absl::InvalidArgumentError(absl::StrCat("unknown command '", command, "' (see --help)"));
  }
  if (!status.ok()) {
    std::fprintf(stderr, "rve_cli: %s\n", std::string(status.message()).c_str());
    return status.code() == absl::StatusCode::kInvalidArgument ? 2 : 1;
  }
  return 0;
}

}  // namespace
}  // namespace rvehub::cli

int main(int argc, char** argv) { return rvehub::cli::Main(argc, argv); }
