// rve_cli: RVEHub's command-line tool. Locally it prepares packings and runs
// element tests; as a client of rve_server it inspects servers and RVEs,
// uploads templates, runs element tests on the server, and checkpoints or
// restores RVEs through HDF5 files.
//
//   rve_cli element-test --test=drained-biaxial --material=SET-dense --seed=1
//       --confining=100000 --strain=0.1 --out=biaxial.csv [--plot=biaxial.png]
//   rve_cli prepare --material=SET-dense --seed=1 [--out=dense.h5]
//   rve_cli upload-template --server=HOST:PORT --file=dense.h5
//   rve_cli element-test --server=HOST:PORT --template=SET-dense-seed1 ...
//   rve_cli info | get | checkpoint | restore | list-runs | drop --server=HOST:PORT ...
//   rve_cli materials
//
// Exit status: 0 success, 1 failure, 2 usage error.
#include <unistd.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <memory>
#include <span>
#include <string>
#include <system_error>
#include <type_traits>
#include <vector>

#include "absl/container/flat_hash_map.h"
#include "absl/flags/flag.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/cord.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/string_view.h"
#include "nlohmann/json.hpp"
#include "rve_server/cli/element_test_io.h"
#include "rve_server/client/channel.h"
#include "rve_server/client/remote_server.h"
#include "rve_server/common/address.h"
#include "rve_server/common/flags.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/common/version.h"
#include "rve_server/embedded/packings.h"
#include "rve_server/values/element_test.h"
#include "rve_server/values/material.h"
#include "rve_server/values/preparation.h"
#include "rve_server/values/record.h"
#include "rve_server/values/snapshot.h"
#include "store/checkpoint.h"

// The options of every command. A command reads an option only when it is
// given (cli::Args), so the defaults live in the commands and their help
// texts, not here.
ABSL_FLAG(std::string, test, "", "element test");
ABSL_FLAG(std::string, material, "", "parameter set");
ABSL_FLAG(uint64_t, seed, 1, "packing seed");
ABSL_FLAG(double, pressure, 0, "preparation pressure, Pa");
ABSL_FLAG(double, void_ratio, 0, "target void ratio of the preparation");
ABSL_FLAG(int, particles, 0, "particle count of the preparation");
ABSL_FLAG(double, rolling_eta, 0, "rolling-resistance eta of the preparation");
ABSL_FLAG(double, confining, 0, "confining stress, Pa");
ABSL_FLAG(double, strain, 0, "strain to stop at");
ABSL_FLAG(std::string, out, "", "output file");
ABSL_FLAG(std::string, plot, "", "plot file");
ABSL_FLAG(int, rows, 0, "rows recorded");
ABSL_FLAG(double, inertial_number, 0, "inertial number");
ABSL_FLAG(std::string, cyclic_control, "", "strain or stress");
ABSL_FLAG(double, amplitude, 0, "cyclic amplitude");
ABSL_FLAG(int, cycles, 0, "cycles");
ABSL_FLAG(std::string, axis, "", "loading axis, x or y");
ABSL_FLAG(std::string, template, "", "template name on the server");
ABSL_FLAG(std::string, name, "", "template name");
ABSL_FLAG(std::string, run, "", "run id");
ABSL_FLAG(int64_t, id, 0, "material-point id");
ABSL_FLAG(bool, tangent, false, "include the tangent");
ABSL_FLAG(std::string, format, "", "text or json");
ABSL_FLAG(std::string, file, "", "input file");
ABSL_FLAG(bool, replace, false, "replace templates of the same name");
ABSL_FLAG(bool, all, false, "every run");
ABSL_FLAG(std::string, server, "", "HOST:PORT");
ABSL_FLAG(std::string, token_file, "", "bearer token file");
ABSL_FLAG(std::string, tls_ca, "", "CA certificate");
ABSL_FLAG(double, timeout, 600, "deadline of each call, s");

namespace rvehub::cli {
namespace {

// ---------------------------------------------------------------------------
// Usage texts.

constexpr char kUsage[] = R"(rve_cli — command-line tool of RVEHub (2-D DEM packings of discs)

Usage: rve_cli COMMAND [--option=value ...]
       rve_cli COMMAND --help      the options of one command

Commands:
  element-test     run an element test on a freshly prepared RVE, writing a CSV (and a
                   PNG); with --server, on a template hosted by an rve_server
  prepare          prepare an RVE and print its initial state; --out saves it as a
                   template file
  materials        the parameter sets and their parameters (cases/REFERENCE.md)
  info             a server's version, limits, load, runs and templates
  get              one hosted RVE's homogenised state (text or JSON)
  upload-template  upload the templates of a template file (from prepare --out)
  checkpoint       export hosted RVEs (one run or all) into an HDF5 file
  contacts         one RVE of an RVE file: its discs and contact forces as CSV
  restore          import RVEs from a checkpoint file into a server
  list-runs        the runs a server hosts (RVEs, steps)
  drop             free a run's RVEs (or one of them) on a server

Server options (info, get, upload-template, checkpoint, restore, list-runs, drop,
element-test --server):
  --server=HOST:PORT   the rve_server to talk to
  --token-file=FILE    file holding the bearer token of a server started with
                       --auth-token-file
  --tls-ca=FILE        PEM CA certificate verifying a TLS server (default: plaintext)
  --timeout=SECONDS    deadline of each call (default 600; 0: none)

Exit status: 0 success, 1 failure (the message names the error code), 2 usage error.
)";

constexpr char kServerOptions[] = R"(
Server options:
  --server=HOST:PORT   the rve_server to talk to
  --token-file=FILE    file holding the bearer token of a server started with
                       --auth-token-file
  --tls-ca=FILE        PEM CA certificate verifying a TLS server (default: plaintext)
  --timeout=SECONDS    deadline of each call (default 600; 0: none)
)";

constexpr char kElementTestHelp[] = R"(rve_cli element-test — run an element test on one RVE

  rve_cli element-test --test=NAME [--material=NAME --seed=N --pressure=PA --void-ratio=E
                       --particles=N --rolling-eta=H] --out=FILE.csv [options]
  rve_cli element-test --server=HOST:PORT --template=NAME --test=NAME --out=FILE.csv [options]

Locally, prepares the packing of --material/--seed and runs the test in this
process. With --server, the server runs the test on a fresh RVE of its template
--template (the packing comes from the template, so --material/--seed do not
apply); the rows come back and are written alike.

Options:
  --test=NAME        drained-biaxial | isotropic | oedometer | undrained-simple-shear |
                     cyclic-simple-shear (default drained-biaxial)
  --material=NAME    parameter set, e.g. SET-dense, SPFEM-biaxial, consolidation
                     (local only; default SET-dense)
  --seed=N           packing seed (local only; default 1)
  --pressure=PA      pressure the packing is compacted at, Pa (local only; default the set's
                     p0); --confining then loads or unloads it from there
  --void-ratio=E     target void ratio of the packing at --pressure, in (0, 1) (local only;
                     default the set's e0; refused when out of the preparation's reach,
                     as for prepare)
  --particles=N      discs in the packing, in [2, 1e6] (local only; default the set's, e.g.
                     400): a larger sample of the same material
  --rolling-eta=H    η of the rolling-resistance limit |M| ≤ η·r_min·fn, in [0, 1], instead
                     of the set's (local only; sets with rolling resistance): another material
  --template=NAME    the server's template to test (with --server)
  --axis=x|y         loading axis of drained-biaxial and oedometer (default y; x holds σyy
                     in the biaxial test): a packing's strength along another direction
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
  --cycles=N         number of cycles (default 5); these three cyclic-simple-shear only
)";

constexpr char kPrepareHelp[] =
    R"(rve_cli prepare — prepare an RVE packing and print its initial state

  rve_cli prepare [--material=NAME] [--seed=N] [--pressure=PA] [--void-ratio=E]
                  [--particles=N] [--rolling-eta=H] [--out=FILE.h5 [--name=NAME]]

Options:
  --material=NAME    parameter set (default SET-dense; see `rve_cli materials`)
  --seed=N           packing seed (default 1)
  --pressure=PA      pressure to compact at, Pa, compression + (default the set's p0): the
                     set's e0 is then sought at this pressure
  --void-ratio=E     target void ratio in (0, 1) instead of the set's e0 (the same material
                     packed denser or looser; the compaction friction, between 0 and the
                     material's, bounds what can be reached: a target beyond that by more
                     than 0.002 is refused, naming the bound; the e0 reached is printed)
  --particles=N      discs in the packing, in [2, 1e6] (default the set's count)
  --rolling-eta=H    η of the rolling-resistance limit |M| ≤ η·r_min·fn, in [0, 1], instead
                     of the set's (sets with rolling resistance, β > 0): another material
  --out=FILE.h5      also write the packing as a template file (for upload-template)
  --name=NAME        template name, [A-Za-z0-9._-]{1,128} (default MATERIAL-seedN, with
                     -pPPa, -eE, -Mdiscs and -etaH added for --pressure, --void-ratio,
                     --particles and --rolling-eta, e.g.
                     SET-dense-seed2-p20000Pa-e0.25-100discs: each makes another packing)
)";

constexpr char kMaterialsHelp[] = R"(rve_cli materials — the parameter sets and their parameters

  rve_cli materials

One line per set: contact law, particle density RHO (kg/m3), contact
modulus E (MPa), KT/KN (linear law), Poisson ratio NU (Hertz–Mindlin),
friction MU, rolling BETA and ETA, bond cohesion C (kPa), local damping,
disc thickness T (m); then the packing: N discs, radii RMIN..RMAX (mm),
pressure P0 (kPa), target void ratio E0 and permeability K0 (m/s).
Sources: cases/REFERENCE.md.
)";

constexpr char kInfoHelp[] = R"(rve_cli info — a server's version, limits, load, runs and templates

  rve_cli info --server=HOST:PORT
)";

constexpr char kGetHelp[] = R"(rve_cli get — one hosted RVE's homogenised state

  rve_cli get --server=HOST:PORT --run=RUN --id=N [--tangent] [--format=text|json]

Prints the committed step, Cauchy stress (Pa, tension +) with p and q
(compression +), void ratio, porosity, coordination (all contacts and without
rattlers), fabric and its anisotropy, permeability, deformation gradient and
contact count; --tangent adds the 9×9 contact tangent D[3i+j][3k+l] (Pa).
--format=json prints one JSON object with the rvehub.v1 RveState field names
(tensors as nested 3×3 or 9×9 arrays). An RVE that cannot be read (unknown id)
exits 1 with the server's message.

Options:
  --run=RUN          run id
  --id=N             material-point id
  --tangent          include the tangent
  --format=FORMAT    text (default) or json
)";

constexpr char kUploadTemplateHelp[] = R"(rve_cli upload-template — upload templates to a server

  rve_cli upload-template --server=HOST:PORT --file=FILE.h5 [--replace]

Uploads every template of a template file (written by `rve_cli prepare --out`
or by a server checkpoint) and prints what the server reports of each.

Options:
  --file=FILE.h5     template file
  --replace          replace templates of the same name (else ALREADY_EXISTS)
)";

constexpr char kCheckpointHelp[] = R"(rve_cli checkpoint — export hosted RVEs into an HDF5 file

  rve_cli checkpoint --server=HOST:PORT --out=FILE.h5 [--run=RUN]

Exports the full state of every RVE of one run (or of every run) and writes
them to FILE.h5 (replaced atomically). The runs are exported one after the
other, so RVEs committed meanwhile may be at different steps.

Options:
  --out=FILE.h5      output file
  --run=RUN          only this run (default: every run)
)";

constexpr char kRestoreHelp[] = R"(rve_cli restore — import RVEs from a checkpoint file

  rve_cli restore --server=HOST:PORT --file=FILE.h5 [--run=RUN]

Imports the RVEs of FILE.h5 (from `rve_cli checkpoint` or a server's rves.h5).
All or nothing: ALREADY_EXISTS when any (run, id) is already hosted.

Options:
  --file=FILE.h5     checkpoint file
  --run=RUN          only the records of this run
)";

constexpr char kListRunsHelp[] = R"(rve_cli list-runs — the runs a server hosts

  rve_cli list-runs --server=HOST:PORT

One line per run, tab-separated: run id, RVEs, smallest and largest committed
step (after a header line RUN, RVES, MIN_STEP, MAX_STEP).
)";

constexpr char kDropHelp[] = R"(rve_cli drop — free a run's RVEs on a server

  rve_cli drop --server=HOST:PORT --run=RUN [--id=N]

Drops every RVE of run RUN (or only material point N) and prints how many.
A run that a crashed or killed mpm_client left behind stays on the server
until it is dropped (`rve_cli list-runs` shows it). NOT_FOUND for an unknown
run.

Options:
  --run=RUN          run id
  --id=N             only this material-point id
)";

constexpr char kContactsHelp[] =
    R"(rve_cli contacts — one RVE's discs and contact forces, for force-chain plots

  rve_cli contacts --file=RVES.h5 --out=PREFIX [--id=N]

Reads the RVEs of an RVE file (a client's packings-STEP.h5, rve_cli checkpoint's
output), takes the one of material-point id N (default: the first), and writes
PREFIX-discs.csv (x_m, y_m, radius_m: each centre wrapped into the cell) and
PREFIX-contacts.csv (i, j, branch_x_m, branch_y_m, normal_force_N,
tangential_force_N: each active contact, the branch from disc i to the nearest
image of disc j, fn compression +) as the engine's force law gives them. No
server is called.

Options:
  --file=RVES.h5     the RVE file
  --id=N             the material-point id (Gauss point) of the RVE
  --out=PREFIX       output prefix
)";

// ---------------------------------------------------------------------------
// Errors and flags.

// Usage errors (exit 2) carry this payload; every other failure exits 1.
constexpr char kUsagePayload[] = "type.rvehub.dev/rve_cli.UsageError";

absl::Status UsageError(absl::string_view message) {
  absl::Status s = absl::InvalidArgumentError(message);
  s.SetPayload(kUsagePayload, absl::Cord("1"));
  return s;
}

bool IsUsageError(const absl::Status& s) { return s.GetPayload(kUsagePayload).has_value(); }

using Flags = Args;

absl::StatusOr<Flags> ParseFlags(int argc, char** argv, int first,
                                 const std::vector<std::string>& known) {
  ArgSpec spec;
  spec.allowed = {known.begin(), known.end()};
  spec.positional = false;
  absl::StatusOr<Flags> flags = ParseArgs(argc, argv, first, spec);
  if (!flags.ok()) return UsageError(flags.status().message());
  return flags;
}

// Reads --key into `out` when given (absent: `out` keeps the command's
// default, which its help text states).
template <typename T>
absl::Status Get(const Flags& flags, const std::string& key, T* out) {
  auto it = flags.text.find(key);
  if (it == flags.text.end()) return absl::OkStatus();
  absl::optional<T> value = FlagValue<T>(key);
  if (!value.has_value()) {
    return absl::InternalError(absl::StrCat("--", key, " is not read as its flag's type"));
  }
  bool ok = true;
  if constexpr (std::is_same_v<T, double>) ok = std::isfinite(*value);
  if constexpr (std::is_same_v<T, std::string>) ok = !value->empty();
  if (!ok) return UsageError(absl::StrCat("bad value for --", key, ": '", it->second, "'"));
  *out = *std::move(value);
  return absl::OkStatus();
}

// A switch: --key, --key=true or --key=false.
absl::Status GetBool(const Flags& flags, const std::string& key, bool* out) {
  return Get(flags, key, out);
}

absl::Status Require(const Flags& flags, const std::string& key, absl::string_view form,
                     std::string* out) {
  RETURN_IF_ERROR(Get(flags, key, out));
  if (out->empty()) return UsageError(absl::StrCat("--", key, "=", form, " is required"));
  return absl::OkStatus();
}

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::string CreatedBy() { return absl::StrCat("rve_cli ", kVersion); }

// ---------------------------------------------------------------------------
// Talking to a server.

const std::vector<std::string> kServerFlags = {"server", "token-file", "tls-ca", "timeout"};

std::vector<std::string> WithServerFlags(std::vector<std::string> flags) {
  flags.insert(flags.end(), kServerFlags.begin(), kServerFlags.end());
  return flags;
}

// Servers are reached only through the client library's RemoteServer, whose
// errors name the server ("RVE server HOST:PORT: ...").
using Remote = std::unique_ptr<client::RemoteServer>;

// Where and how to reach a server, from the server options (usage errors
// before any file is read or call made).
struct ServerOptions {
  std::string target;
  client::ClientOptions client;
  client::RemoteOptions remote;
};

absl::StatusOr<ServerOptions> ReadServerOptions(const Flags& flags) {
  ServerOptions out;
  RETURN_IF_ERROR(Require(flags, "server", "HOST:PORT", &out.target));
  if (absl::Status s = ValidateAddress("--server", out.target, PortZero::kRefused); !s.ok()) {
    return UsageError(s.message());
  }
  double timeout = 600;
  RETURN_IF_ERROR(Get(flags, "timeout", &timeout));
  if (timeout < 0 || timeout > 1e9) return UsageError("--timeout must lie in [0, 1e9] seconds");
  std::string token_file, tls_ca;
  RETURN_IF_ERROR(Get(flags, "token-file", &token_file));
  RETURN_IF_ERROR(Get(flags, "tls-ca", &tls_ca));
  ASSIGN_OR_RETURN(out.client, client::ClientOptionsFromFiles(token_file, tls_ca));
  // Every call gets --timeout as its deadline; 0: none.
  const absl::Duration deadline = timeout > 0 ? absl::Seconds(timeout) : absl::InfiniteDuration();
  out.remote.connect_timeout = out.remote.call_timeout = out.remote.create_timeout = deadline;
  return out;
}

absl::StatusOr<Remote> Connect(const ServerOptions& server) {
  return client::RemoteServer::Connect(server.target, server.client, server.remote);
}

absl::StatusOr<Remote> Connect(const Flags& flags) {
  ASSIGN_OR_RETURN(ServerOptions server, ReadServerOptions(flags));
  return Connect(server);
}

// ---------------------------------------------------------------------------
// Output helpers.

// One updating line on a terminal; a line every 10 % in a log file.
class ProgressLine {
 public:
  explicit ProgressLine(std::string label)
      : label_(std::move(label)),
        tty_(isatty(fileno(stderr))),
        start_(std::chrono::steady_clock::now()) {}

  void Update(double fraction) {
    const int every = tty_ ? 1 : 10;
    const int percent = static_cast<int>(fraction * 100) / every * every;
    if (percent == last_percent_) return;
    last_percent_ = percent;
    std::fprintf(stderr, "%s%s: %3d%% (%.1f s)%s", tty_ ? "\r" : "", label_.c_str(), percent,
                 SecondsSince(start_), tty_ ? "" : "\n");
    std::fflush(stderr);
  }

  void Done() {
    if (tty_ && last_percent_ >= 0) std::fprintf(stderr, "\n");
  }

 private:
  const std::string label_;
  const bool tty_;
  const std::chrono::steady_clock::time_point start_;
  int last_percent_ = -1;
};

// Field order as in rvehub.v1.RveState (nlohmann writes doubles so that they
// read back bit for bit, and NaN or infinity as null).
using Json = nlohmann::ordered_json;

// A matrix as nested JSON arrays, one a row.
template <typename Matrix>
Json JsonMatrix(const Matrix& m) {
  Json rows = Json::array();
  for (int r = 0; r < m.rows(); ++r) {
    Json row = Json::array();
    for (int c = 0; c < m.cols(); ++c) row.push_back(m(r, c));
    rows.push_back(std::move(row));
  }
  return rows;
}

constexpr int kKeyWidth = 26;

void PrintValue(absl::string_view key, const std::string& value) {
  std::printf("%-*s %s\n", kKeyWidth, std::string(key).c_str(), value.c_str());
}

// A matrix, one row a line, under `key`.
template <typename Matrix>
void PrintMatrix(absl::string_view key, const Matrix& m) {
  for (int r = 0; r < m.rows(); ++r) {
    std::string row;
    for (int c = 0; c < m.cols(); ++c) absl::StrAppendFormat(&row, " %16.9g", m(r, c));
    std::printf("%-*s%s\n", kKeyWidth, r == 0 ? std::string(key).c_str() : "", row.c_str());
  }
}

// ---------------------------------------------------------------------------
// Local commands.

// A packing prepared here from --material, --seed and the variant options.
struct LocalPacking {
  std::string material;
  std::uint64_t seed = 1;
  dem::TemplateVariant variant;
  dem::PreparationReport report;
  TemplateRecord record;  // named and described as the preparation does
};

absl::StatusOr<LocalPacking> PreparePacking(const Flags& flags) {
  LocalPacking out;
  out.material = "SET-dense";
  dem::TemplateVariant& v = out.variant;
  RETURN_IF_ERROR(Get(flags, "material", &out.material));
  RETURN_IF_ERROR(Get(flags, "seed", &out.seed));
  RETURN_IF_ERROR(Get(flags, "pressure", &v.pressure));
  // The message spells the bound as people write it; StrCat would print 1e+09.
  static_assert(dem::kMaxPressure == 1e9, "--pressure's usage message states the bound");
  if (flags.contains("pressure") && !(v.pressure > 0 && v.pressure <= dem::kMaxPressure)) {
    return UsageError("--pressure must be a pressure in (0, 1e9] Pa");
  }
  RETURN_IF_ERROR(Get(flags, "void-ratio", &v.void_ratio));
  if (flags.contains("void-ratio") && !(v.void_ratio > 0 && v.void_ratio < 1)) {
    return UsageError("--void-ratio must lie in (0, 1)");
  }
  RETURN_IF_ERROR(Get(flags, "particles", &v.num_particles));
  if (flags.contains("particles") &&
      !(v.num_particles >= 2 && static_cast<std::size_t>(v.num_particles) <= dem::kMaxParticles)) {
    return UsageError(absl::StrCat("--particles must lie in [2, ", dem::kMaxParticles, "]"));
  }
  if (flags.contains("rolling-eta")) {
    double eta = 0;
    RETURN_IF_ERROR(Get(flags, "rolling-eta", &eta));
    if (!(eta >= 0 && eta <= dem::kMaxRollingEta)) {
      return UsageError(absl::StrCat("--rolling-eta must lie in [0, ", dem::kMaxRollingEta, "]"));
    }
    v.rolling_eta = eta;
  }
  std::fprintf(stderr, "preparing %s...\n", out.material.c_str());
  // Its first line is "N discs, seed S".
  ASSIGN_OR_RETURN(out.record, embedded::PrepareTemplate(out.material, out.seed, v, &out.report,
                                                         [](const std::string& line) {
                                                           std::fprintf(stderr, "  %s\n",
                                                                        line.c_str());
                                                         }));
  const dem::PreparationReport& r = out.report;
  std::fprintf(
      stderr, "prepared: e0 = %.4f, p0 = %.1f Pa, Z = %.2f, compaction friction %.4f, %lld steps\n",
      r.void_ratio, r.pressure, r.coordination, r.compaction_friction,
      static_cast<long long>(r.steps));
  return out;
}

// RunElementTest on the server: progress on stderr, the rows at the end.
absl::StatusOr<std::vector<dem::ElementTestRow>> RunOnServer(const Flags& flags,
                                                             const dem::ElementTestSpec& spec,
                                                             const std::string& test,
                                                             const std::string& template_name) {
  ASSIGN_OR_RETURN(Remote remote, Connect(flags));
  ProgressLine progress(absl::StrCat(test, " on ", template_name, " at ", remote->name()));
  absl::StatusOr<std::vector<dem::ElementTestRow>> rows = remote->RunElementTest(
      template_name, spec, [&](double fraction) { progress.Update(fraction); });
  progress.Done();
  return rows;
}

absl::Status ElementTestCommand(const Flags& flags) {
  dem::ElementTestSpec spec;
  std::string test = "drained-biaxial", out, plot_path, cyclic = "strain", template_name;
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
  RETURN_IF_ERROR(Get(flags, "template", &template_name));
  std::string axis = "y";
  RETURN_IF_ERROR(Get(flags, "axis", &axis));
  if (out.empty()) return UsageError("--out=FILE.csv is required");
  if (axis != "x" && axis != "y") return UsageError("--axis must be x or y");
  spec.axis = axis == "x" ? 0 : 1;
  absl::StatusOr<dem::ElementTestKind> kind = dem::ParseElementTestKind(test);
  if (!kind.ok()) return UsageError(kind.status().message());
  spec.kind = *kind;
  if (spec.axis != 1 && !dem::HasLoadingAxis(spec.kind)) {
    return UsageError("--axis applies to drained-biaxial and oedometer only");
  }
  // Ignored, they would hide a typo in --test (an --amplitude=-1e308 on a
  // biaxial test ran).
  if (spec.kind != dem::ElementTestKind::kCyclicSimpleShear) {
    for (const char* key : {"amplitude", "cycles", "cyclic-control"}) {
      if (flags.contains(key)) {
        return UsageError(absl::StrCat("--", key, " applies to cyclic-simple-shear only"));
      }
    }
  }
  if (cyclic == "strain") {
    spec.cyclic_control = dem::CyclicControl::kStrain;
  } else if (cyclic == "stress") {
    spec.cyclic_control = dem::CyclicControl::kStress;
  } else {
    return UsageError("--cyclic-control must be strain or stress");
  }

  const bool on_server = flags.contains("server");
  std::string title;
  absl::StatusOr<std::vector<dem::ElementTestRow>> rows;
  if (on_server) {
    // The template fixes the packing: a material or seed here would be
    // silently ignored, which is worse than refusing it.
    for (const char* key :
         {"material", "seed", "pressure", "void-ratio", "particles", "rolling-eta"}) {
      if (flags.contains(key)) {
        return UsageError(absl::StrCat(
            "--", key, " does not apply with --server (the template fixes the packing)"));
      }
    }
    if (template_name.empty()) return UsageError("--template=NAME is required with --server");
    title = absl::StrCat(test, " on ", template_name);
    rows = RunOnServer(flags, spec, test, template_name);
  } else {
    for (const std::string& key : WithServerFlags({"template"})) {
      if (flags.contains(key)) return UsageError(absl::StrCat("--", key, " needs --server"));
    }
    ASSIGN_OR_RETURN(LocalPacking local, PreparePacking(flags));
    title = absl::StrCat(test, " on ", local.record.name);
    ProgressLine progress(title);
    rows = embedded::RunElementTest(std::move(local.record.packing), spec,
                                    [&](double fraction) { progress.Update(fraction); });
    progress.Done();
  }
  if (!rows.ok()) return rows.status();
  RETURN_IF_ERROR(WriteElementTestCsv(out, *rows));
  std::fprintf(stderr, "wrote %zu rows to %s\n", rows->size(), out.c_str());
  if (!plot_path.empty()) {
    RETURN_IF_ERROR(WriteElementTestPlot(plot_path, spec.kind, title, *rows));
    std::fprintf(stderr, "wrote plot to %s\n", plot_path.c_str());
  }
  return absl::OkStatus();
}

absl::Status PrepareCommand(const Flags& flags) {
  std::string out, name;
  RETURN_IF_ERROR(Get(flags, "out", &out));
  RETURN_IF_ERROR(Get(flags, "name", &name));
  if (!name.empty() && out.empty()) return UsageError("--name needs --out=FILE.h5");
  // A bad name would only be refused at upload, after the preparation.
  if (!name.empty()) {
    if (absl::Status s = client::ValidateName("--name", name); !s.ok()) {
      return UsageError(s.message());
    }
  }
  ASSIGN_OR_RETURN(LocalPacking local, PreparePacking(flags));
  ASSIGN_OR_RETURN(const dem::RveState s,
                   embedded::Observe(local.record.packing, /*want_tangent=*/true));
  std::printf("material %s\nparticles %d\nvoid_ratio %.6f\nporosity %.6f\n", local.material.c_str(),
              static_cast<int>(local.record.packing.radius.size()), s.void_ratio, s.porosity);
  std::printf("p_Pa %.3f\nsxx_Pa %.3f\nsyy_Pa %.3f\nsxy_Pa %.3f\n", s.MeanPressure(),
              -s.stress(0, 0), -s.stress(1, 1), -s.stress(0, 1));
  std::printf(
      "coordination %.4f\nmechanical_coordination %.4f\nFa %.5f\npermeability_m_per_s %.6g\n",
      s.coordination, s.mechanical_coordination, s.fabric_anisotropy, s.permeability);
  std::printf("unbalanced_force_ratio %.3g\ntime_step_s %.6g\nD_xxxx_Pa %.6g\nD_yyyy_Pa %.6g\n",
              s.unbalanced_force_ratio, s.time_step, (*s.tangent)(0, 0), (*s.tangent)(4, 4));
  if (out.empty()) return absl::OkStatus();

  TemplateRecord& record = local.record;
  if (!name.empty()) record.name = name;
  store::FileInfo info;
  info.created_by = CreatedBy();
  RETURN_IF_ERROR(store::WriteTemplates(out, std::span<const TemplateRecord>(&record, 1), info));
  std::printf("template %s\nwrote %s\n", record.name.c_str(), out.c_str());
  return absl::OkStatus();
}

// One line per set: its contact law and particle parameters, then how its
// packings are prepared (the units are in the header).
absl::Status MaterialsCommand(const Flags&) {
  std::printf("%-20s %-13s %7s %9s %6s %5s %6s %5s %5s %7s %5s %5s %5s %7s %7s %8s %6s %7s\n",
              "NAME", "CONTACT", "RHO", "E_MPA", "KT/KN", "NU", "MU", "BETA", "ETA", "C_KPA",
              "DAMP", "T_M", "N", "RMIN_MM", "RMAX_MM", "P0_KPA", "E0", "K0_M/S");
  for (const std::string& name : dem::ParameterSetNames()) {
    ASSIGN_OR_RETURN(dem::ParameterSet set, dem::FindParameterSet(name));
    const dem::Material& m = set.material;
    const dem::PreparationSpec& p = set.preparation;
    std::printf(
        "%-20s %-13s %7.0f %9.4g %6.3g %5.3g %6.4g %5.3g %5.3g %7.4g %5.3g %5.3g %5d %7.3g %7.3g "
        "%8.4g %6.4g %7.3g\n",
        name.c_str(), m.model == dem::ContactModel::kLinear ? "linear" : "hertz-mindlin", m.density,
        m.young_modulus * 1e-6, m.stiffness_ratio, m.poisson_ratio, m.friction, m.rolling_beta,
        m.rolling_eta, m.bond_cohesion * 1e-3, m.damping, m.thickness, p.num_particles,
        p.radius_min * 1e3, p.radius_max * 1e3, p.pressure * 1e-3, p.target_void_ratio,
        p.initial_permeability);
  }
  return absl::OkStatus();
}

// A store file of the wrong kind says which tool reads it. The store names
// its kind in the message ("... holds 'simulation', not 'rves' ..."); a
// test pins that text.
absl::Status ExplainFileKind(const absl::Status& s, const std::string& file) {
  if (!absl::IsInvalidArgument(s)) return s;
  const absl::string_view m = s.message();
  if (absl::StrContains(m, "holds 'simulation'")) {
    return absl::InvalidArgumentError(
        absl::StrCat(file,
                     " is an mpm_client checkpoint (a whole MPM simulation), not RVEs of a server: "
                     "continue it with `mpm_client resume ",
                     file, "`"));
  }
  if (absl::StrContains(m, "holds 'templates'")) {
    return absl::InvalidArgumentError(absl::StrCat(
        file, " is a template file: upload it with `rve_cli upload-template --file=", file, "`"));
  }
  if (absl::StrContains(m, "holds 'rves'")) {
    return absl::InvalidArgumentError(absl::StrCat(
        file, " is a checkpoint of server RVEs: import it with `rve_cli restore --file=", file,
        "`"));
  }
  if (absl::StrContains(m, "holds 'results'")) {
    return absl::InvalidArgumentError(absl::StrCat(
        file, " holds the results of an mpm_client run (open results.xdmf in ParaView)"));
  }
  return s;
}

// ---------------------------------------------------------------------------
// Server commands.

std::string Mib(std::int64_t bytes) {
  return absl::StrFormat("%.1f MiB", static_cast<double>(bytes) / (1 << 20));
}

absl::Status InfoCommand(const Flags& flags) {
  ASSIGN_OR_RETURN(Remote remote, Connect(flags));
  ASSIGN_OR_RETURN(client::ServerInfo info, remote->GetServerInfo());
  ASSIGN_OR_RETURN(std::vector<RunInfo> runs, remote->ListRuns());
  ASSIGN_OR_RETURN(std::vector<TemplateInfo> templates, remote->ListTemplates());

  std::printf("server     %s\n", remote->name().c_str());
  std::printf("version    %s (%s), up %.1f s\n", info.version.c_str(), info.api_version.c_str(),
              info.uptime_seconds);
  std::printf("threads    %d\n", info.threads);
  std::printf("RVEs       %lld of at most %lld, in %lld runs\n",
              static_cast<long long>(info.num_rves), static_cast<long long>(info.max_rves),
              static_cast<long long>(info.num_runs));
  std::printf("memory     %s of at most %s\n", Mib(info.memory_bytes).c_str(),
              Mib(info.max_memory_bytes).c_str());
  std::printf("limits     %lld RVEs per call, %s per message",
              static_cast<long long>(info.max_batch), Mib(info.max_message_bytes).c_str());
  if (info.max_templates > 0) {
    std::printf(", %lld templates", static_cast<long long>(info.max_templates));
  }
  std::printf("\n");
  std::printf("security   authentication %s, TLS %s\n", info.auth_required ? "on" : "off",
              info.tls ? "on" : "off");

  std::printf("\nruns: %d\n", static_cast<int>(runs.size()));
  if (!runs.empty()) {
    int width = 3;
    for (const RunInfo& r : runs) width = std::max<int>(width, r.run_id.size());
    std::printf("  %-*s %10s  %s\n", width, "RUN", "RVES", "STEPS");
    for (const RunInfo& r : runs) {
      const std::string steps = r.min_step == r.max_step
                                    ? absl::StrCat(r.min_step)
                                    : absl::StrCat(r.min_step, "..", r.max_step);
      std::printf("  %-*s %10lld  %s\n", width, r.run_id.c_str(),
                  static_cast<long long>(r.num_rves), steps.c_str());
    }
  }
  std::printf("\ntemplates: %d\n", static_cast<int>(templates.size()));
  if (!templates.empty()) {
    int width = 4, material_width = 8;
    for (const TemplateInfo& t : templates) {
      width = std::max<int>(width, t.name.size());
      material_width = std::max<int>(material_width, t.material_name.size());
    }
    std::printf("  %-*s %9s %10s %14s  %-*s  %s\n", width, "NAME", "PARTICLES", "VOID_RATIO",
                "P_PA", material_width, "MATERIAL", "DESCRIPTION");
    for (const TemplateInfo& t : templates) {
      std::printf("  %-*s %9lld %10.4f %14.1f  %-*s  %s\n", width, t.name.c_str(),
                  static_cast<long long>(t.num_particles), t.void_ratio, t.mean_pressure,
                  material_width, t.material_name.c_str(), t.description.c_str());
    }
  }
  return absl::OkStatus();
}

void PrintStateText(const std::string& run, const RveOutcome& r) {
  const dem::RveState& s = r.state;
  PrintValue("run", run);
  PrintValue("id", absl::StrCat(r.id));
  PrintValue("step", absl::StrCat(r.step));
  PrintMatrix("stress_Pa (tension +)", s.stress);
  PrintValue("p_Pa (compression +)", absl::StrFormat("%.10g", s.MeanPressure()));
  PrintValue("q_Pa", absl::StrFormat("%.10g", s.DeviatorStress()));
  PrintValue("void_ratio", absl::StrFormat("%.10g", s.void_ratio));
  PrintValue("porosity", absl::StrFormat("%.10g", s.porosity));
  PrintValue("coordination", absl::StrFormat("%.10g", s.coordination));
  PrintValue("mechanical_coordination", absl::StrFormat("%.10g", s.mechanical_coordination));
  PrintValue("contacts", absl::StrCat(s.num_contacts));
  PrintMatrix(s.fabric_defined ? "fabric" : "fabric (no contacts)", s.fabric);
  PrintMatrix("fabric_anisotropy_tensor", s.fabric_anisotropy_tensor);
  PrintValue("Fa", absl::StrFormat("%.10g", s.fabric_anisotropy));
  PrintValue("permeability_m_per_s", absl::StrFormat("%.10g", s.permeability));
  PrintMatrix("F", r.deformation_gradient);
  PrintValue("mean_rotation_rad", absl::StrFormat("%.10g", s.mean_rotation));
  PrintValue("kinetic_energy_J", absl::StrFormat("%.10g", s.kinetic_energy));
  PrintValue("unbalanced_force_ratio", absl::StrFormat("%.10g", s.unbalanced_force_ratio));
  PrintValue("volume_m3", absl::StrFormat("%.10g", s.volume));
  PrintValue("last_call_dem_steps", absl::StrCat(s.steps));
  PrintValue("time_step_s", absl::StrFormat("%.10g", s.time_step));
  PrintValue("mass_scale", absl::StrFormat("%.10g", s.mass_scale));
  if (s.tangent) {
    PrintValue("tangent_Pa", "D[3i+j][3k+l], rows and columns xx xy xz yx yy yz zx zy zz");
    PrintMatrix("", *s.tangent);
  }
}

void PrintStateJson(const std::string& run, const RveOutcome& r) {
  const dem::RveState& s = r.state;
  Json j = {
      {"run_id", run},
      {"id", r.id},
      {"step", r.step},
      {"stress", JsonMatrix(s.stress)},
      {"mean_pressure", s.MeanPressure()},
      {"deviator_stress", s.DeviatorStress()},
      {"void_ratio", s.void_ratio},
      {"porosity", s.porosity},
      {"coordination", s.coordination},
      {"mechanical_coordination", s.mechanical_coordination},
      {"num_contacts", s.num_contacts},
      {"fabric_defined", s.fabric_defined},
      {"fabric", JsonMatrix(s.fabric)},
      {"fabric_anisotropy_tensor", JsonMatrix(s.fabric_anisotropy_tensor)},
      {"fabric_anisotropy", s.fabric_anisotropy},
      {"permeability", s.permeability},
      {"deformation_gradient", JsonMatrix(r.deformation_gradient)},
      {"mean_rotation", s.mean_rotation},
      {"kinetic_energy", s.kinetic_energy},
      {"unbalanced_force_ratio", s.unbalanced_force_ratio},
      {"volume", s.volume},
      {"steps", s.steps},
      {"time_step", s.time_step},
      {"mass_scale", s.mass_scale},
  };
  if (s.tangent) j["tangent"] = JsonMatrix(*s.tangent);
  // Invalid UTF-8 in a run id is replaced rather than thrown about.
  std::printf("%s\n", j.dump(-1, ' ', false, Json::error_handler_t::replace).c_str());
}

absl::Status GetCommand(const Flags& flags) {
  std::string run, format = "text";
  std::int64_t id = 0;
  bool tangent = false;
  RETURN_IF_ERROR(Require(flags, "run", "RUN", &run));
  if (!flags.contains("id")) return UsageError("--id=N is required");
  RETURN_IF_ERROR(Get(flags, "id", &id));
  RETURN_IF_ERROR(GetBool(flags, "tangent", &tangent));
  RETURN_IF_ERROR(Get(flags, "format", &format));
  if (format != "text" && format != "json") return UsageError("--format must be text or json");
  ASSIGN_OR_RETURN(Remote remote, Connect(flags));
  const std::int64_t ids[] = {id};
  ASSIGN_OR_RETURN(std::vector<RveOutcome> states, remote->Get(run, ids, tangent));
  const RveOutcome& r = states.front();
  if (!r.status.ok()) return r.status;
  if (format == "json") {
    PrintStateJson(run, r);
  } else {
    PrintStateText(run, r);
  }
  return absl::OkStatus();
}

absl::Status UploadTemplateCommand(const Flags& flags) {
  std::string file;
  bool replace = false;
  RETURN_IF_ERROR(Require(flags, "file", "FILE.h5", &file));
  RETURN_IF_ERROR(GetBool(flags, "replace", &replace));
  ASSIGN_OR_RETURN(const ServerOptions server, ReadServerOptions(flags));
  // The file is read before the server is called: a wrong file is refused
  // without one.
  absl::StatusOr<std::vector<TemplateRecord>> templates = store::ReadTemplates(file);
  if (!templates.ok()) return ExplainFileKind(templates.status(), file);
  if (templates->empty()) {
    return absl::FailedPreconditionError(absl::StrCat("'", file, "' holds no templates"));
  }
  ASSIGN_OR_RETURN(Remote remote, Connect(server));
  for (const TemplateRecord& t : *templates) {
    ASSIGN_OR_RETURN(TemplateInfo info, remote->UploadTemplate(t, replace));
    std::printf("uploaded %s: %lld particles, e = %.4f, p = %.1f Pa, material %s (%s)\n",
                info.name.c_str(), static_cast<long long>(info.num_particles), info.void_ratio,
                info.mean_pressure, info.material_name.c_str(), info.description.c_str());
  }
  return absl::OkStatus();
}

absl::Status ContactsCommand(const Flags& flags) {
  std::string file, out;
  RETURN_IF_ERROR(Require(flags, "file", "RVES.h5", &file));
  RETURN_IF_ERROR(Require(flags, "out", "PREFIX", &out));
  const bool any = !flags.contains("id");  // the first RVE
  std::int64_t id = 0;
  if (!any) {
    RETURN_IF_ERROR(Get(flags, "id", &id));
    if (id < 0) return UsageError(absl::StrCat("--id must be a material-point id >= 0, got ", id));
  }
  absl::StatusOr<std::vector<RveRecord>> all = store::ReadRves(file);
  if (!all.ok()) return ExplainFileKind(all.status(), file);
  const RveRecord* rve = nullptr;
  for (const RveRecord& r : *all) {
    if (any || r.id == id) {
      rve = &r;
      break;
    }
  }
  if (rve == nullptr) {
    return absl::NotFoundError(any ? absl::StrCat("'", file, "' holds no RVE")
                                   : absl::StrCat("'", file, "' holds no RVE of id ", id));
  }
  ASSIGN_OR_RETURN(const embedded::PackingForces forces, embedded::ContactForces(rve->packing));
  const std::string discs = out + "-discs.csv", contacts = out + "-contacts.csv";
  std::string text = "x_m,y_m,radius_m\n";
  for (std::size_t k = 0; k < forces.radius.size(); ++k) {
    absl::StrAppendFormat(&text, "%.9g,%.9g,%.9g\n", forces.position[k].x(), forces.position[k].y(),
                          forces.radius[k]);
  }
  RETURN_IF_ERROR(cli::WriteTextFile(discs, text));
  text = "i,j,branch_x_m,branch_y_m,normal_force_N,tangential_force_N\n";
  for (const embedded::PackingContact& c : forces.contacts) {
    absl::StrAppendFormat(&text, "%d,%d,%.9g,%.9g,%.9g,%.9g\n", c.i, c.j, c.branch.x(),
                          c.branch.y(), c.normal_force, c.tangential_force);
  }
  RETURN_IF_ERROR(cli::WriteTextFile(contacts, text));
  std::printf("RVE %lld of run \"%s\" (step %lld): %zu discs, %zu contacts -> %s, %s\n",
              static_cast<long long>(rve->id), rve->run_id.c_str(),
              static_cast<long long>(rve->step), forces.radius.size(), forces.contacts.size(),
              discs.c_str(), contacts.c_str());
  return absl::OkStatus();
}

absl::Status CheckpointCommand(const Flags& flags) {
  std::string out, run;
  RETURN_IF_ERROR(Require(flags, "out", "FILE.h5", &out));
  RETURN_IF_ERROR(Get(flags, "run", &run));
  ASSIGN_OR_RETURN(Remote remote, Connect(flags));
  const auto start = std::chrono::steady_clock::now();
  std::vector<std::string> runs;
  if (!run.empty()) {
    runs.push_back(run);
  } else {
    ASSIGN_OR_RETURN(std::vector<RunInfo> list, remote->ListRuns());
    for (const RunInfo& r : list) runs.push_back(r.run_id);
  }
  std::vector<RveRecord> records;
  for (const std::string& r : runs) {
    RETURN_IF_ERROR(remote->Export(r, {}, [&records](RveRecord&& record) {
      records.push_back(std::move(record));
      return absl::OkStatus();
    }));
  }
  store::FileInfo info;
  info.created_by = CreatedBy();
  RETURN_IF_ERROR(store::WriteRves(out, records, info));
  std::error_code error;
  const std::uintmax_t bytes = std::filesystem::file_size(out, error);
  std::printf("wrote %zu RVEs of %zu runs to %s (%llu bytes, %.2f s)\n", records.size(),
              runs.size(), out.c_str(), error ? 0ULL : static_cast<unsigned long long>(bytes),
              SecondsSince(start));
  return absl::OkStatus();
}

absl::Status RestoreCommand(const Flags& flags) {
  std::string file, run;
  RETURN_IF_ERROR(Require(flags, "file", "FILE.h5", &file));
  RETURN_IF_ERROR(Get(flags, "run", &run));
  ASSIGN_OR_RETURN(const ServerOptions server, ReadServerOptions(flags));
  const auto start = std::chrono::steady_clock::now();
  // The file is read before the server is called: a wrong file is refused
  // without one.
  absl::StatusOr<std::vector<RveRecord>> all = store::ReadRves(file);
  if (!all.ok()) return ExplainFileKind(all.status(), file);
  std::vector<RveRecord> records;
  for (RveRecord& r : *all) {
    if (run.empty() || r.run_id == run) records.push_back(std::move(r));
  }
  if (records.empty() && !run.empty()) {
    return absl::NotFoundError(absl::StrCat("'", file, "' holds no RVE of run \"", run, "\""));
  }
  if (records.empty()) {
    std::printf("imported 0 RVEs (%s holds none)\n", file.c_str());
    return absl::OkStatus();
  }
  ASSIGN_OR_RETURN(Remote remote, Connect(server));
  ASSIGN_OR_RETURN(client::ImportSummary imported, remote->ImportRecords(std::move(records)));
  std::printf("imported %lld RVEs into %s (%lld chunks, %.2f s)\n",
              static_cast<long long>(imported.imported), remote->name().c_str(),
              static_cast<long long>(imported.chunks), SecondsSince(start));
  return absl::OkStatus();
}

// The runs a server hosts: one line each (tab-separated, for scripts).
absl::Status ListRunsCommand(const Flags& flags) {
  ASSIGN_OR_RETURN(Remote remote, Connect(flags));
  ASSIGN_OR_RETURN(std::vector<RunInfo> runs, remote->ListRuns());
  std::printf("RUN\tRVES\tMIN_STEP\tMAX_STEP\n");
  for (const RunInfo& r : runs) {
    std::printf("%s\t%lld\t%lld\t%lld\n", r.run_id.c_str(), static_cast<long long>(r.num_rves),
                static_cast<long long>(r.min_step), static_cast<long long>(r.max_step));
  }
  return absl::OkStatus();
}

// Frees a run's RVEs on a server (all of them, or the ids of --id).
absl::Status DropCommand(const Flags& flags) {
  std::string run;
  RETURN_IF_ERROR(Require(flags, "run", "RUN", &run));
  std::vector<std::int64_t> ids;
  if (flags.contains("id")) {
    std::int64_t id = 0;
    RETURN_IF_ERROR(Get(flags, "id", &id));
    ids.push_back(id);
  }
  ASSIGN_OR_RETURN(Remote remote, Connect(flags));
  ASSIGN_OR_RETURN(std::int64_t dropped, remote->DropRves(run, ids));
  std::printf("dropped %lld RVEs of run %s on %s\n", static_cast<long long>(dropped), run.c_str(),
              remote->name().c_str());
  return absl::OkStatus();
}

// ---------------------------------------------------------------------------
// Dispatch.

struct Command {
  const char* name;
  const char* help;
  bool server;  // takes the server options
  std::vector<std::string> flags;
  absl::Status (*run)(const Flags&);
};

const std::vector<Command>& Commands() {
  static const auto* commands = new std::vector<Command>{
      {"element-test",
       kElementTestHelp,
       true,
       {"test", "material", "seed", "pressure", "void-ratio", "particles", "rolling-eta",
        "confining", "strain", "out", "plot", "rows", "inertial-number", "cyclic-control",
        "amplitude", "cycles", "template", "axis"},
       &ElementTestCommand},
      {"prepare",
       kPrepareHelp,
       false,
       {"material", "seed", "pressure", "void-ratio", "particles", "rolling-eta", "out", "name"},
       &PrepareCommand},
      {"materials", kMaterialsHelp, false, {}, &MaterialsCommand},
      {"info", kInfoHelp, true, {}, &InfoCommand},
      {"get", kGetHelp, true, {"run", "id", "tangent", "format"}, &GetCommand},
      {"upload-template", kUploadTemplateHelp, true, {"file", "replace"}, &UploadTemplateCommand},
      {"checkpoint", kCheckpointHelp, true, {"out", "run"}, &CheckpointCommand},
      {"contacts", kContactsHelp, false, {"file", "id", "out"}, &ContactsCommand},
      {"restore", kRestoreHelp, true, {"file", "run"}, &RestoreCommand},
      {"list-runs", kListRunsHelp, true, {}, &ListRunsCommand},
      {"drop", kDropHelp, true, {"run", "id"}, &DropCommand},
  };
  return *commands;
}

void PrintHelp(const Command& c) {
  std::fputs(c.help, stdout);
  if (c.server) std::fputs(kServerOptions, stdout);
}

int Main(int argc, char** argv) {
  const std::string first = argc < 2 ? "" : argv[1];
  if (argc < 2 || first == "--help" || first == "-h" || first == "help") {
    if (first == "help" && argc > 2) {
      for (const Command& c : Commands()) {
        if (argv[2] == std::string(c.name)) {
          PrintHelp(c);
          return 0;
        }
      }
    }
    std::fputs(kUsage, argc < 2 ? stderr : stdout);
    return argc < 2 ? 2 : 0;
  }
  const Command* command = nullptr;
  for (const Command& c : Commands()) {
    if (first == c.name) command = &c;
  }
  absl::Status status;
  if (command == nullptr) {
    status = UsageError(absl::StrCat("unknown command '", first, "' (see --help)"));
  } else {
    for (int i = 2; i < argc; ++i) {
      if (std::string(argv[i]) == "--help" || std::string(argv[i]) == "-h") {
        PrintHelp(*command);
        return 0;
      }
    }
    absl::StatusOr<Flags> flags = ParseFlags(
        argc, argv, 2, command->server ? WithServerFlags(command->flags) : command->flags);
    if (flags.ok()) {
      for (const std::string& warning : flags->warnings) {
        std::fprintf(stderr, "rve_cli: warning: %s\n", warning.c_str());
      }
    }
    status = flags.ok() ? command->run(*flags) : flags.status();
  }
  if (status.ok()) return 0;
  if (IsUsageError(status)) {
    std::fprintf(stderr, "rve_cli: %s\n", std::string(status.message()).c_str());
    return 2;
  }
  std::fprintf(stderr, "rve_cli: %s: %s\n", absl::StatusCodeToString(status.code()).c_str(),
               std::string(status.message()).c_str());
  return 1;
}

}  // namespace
}  // namespace rvehub::cli

int main(int argc, char** argv) { return rvehub::cli::Main(argc, argv); }
