// The record layout shared by every store file that holds RVE and template
// records (record_io.h), and the atomic write and checked open of store files.
#include "store/record_io.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <functional>
#include <iterator>
#include <mutex>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "rve_server/values/material.h"
#include "rve_server/values/snapshot.h"
#include "store/checkpoint.h"
#include "store/hdf5.h"

namespace rvehub::store {
namespace {

using h5::Span;
using internal::HasNul;
using internal::kKindRves;
using internal::kKindSimulation;
using internal::kKindTemplates;
using internal::StoreMutex;

constexpr char kEngine[] =
    "RVEHub DEM engine: 2-D discs in a periodic cell, plane strain; "
    "dem::RveSnapshot state, bit-exact (store/FORMAT.md)";

// Field tables: the dataset name next to the member it holds, so that the
// writer and the reader cannot disagree on a name or forget a field.
struct MaterialField {
  const char* dataset;
  double dem::Material::*member;
};
constexpr MaterialField kMaterialFields[] = {
    {"/material/density", &dem::Material::density},
    {"/material/young_modulus", &dem::Material::young_modulus},
    {"/material/stiffness_ratio", &dem::Material::stiffness_ratio},
    {"/material/poisson_ratio", &dem::Material::poisson_ratio},
    {"/material/friction", &dem::Material::friction},
    {"/material/rolling_beta", &dem::Material::rolling_beta},
    {"/material/rolling_eta", &dem::Material::rolling_eta},
    {"/material/bond_cohesion", &dem::Material::bond_cohesion},
    {"/material/damping", &dem::Material::damping},
    {"/material/thickness", &dem::Material::thickness},
};

struct ControlsField {
  const char* dataset;
  double dem::Controls::*member;
};
constexpr ControlsField kControlsFields[] = {
    {"/controls/time_step_factor", &dem::Controls::time_step_factor},
    {"/controls/max_inertial_number", &dem::Controls::max_inertial_number},
    {"/controls/pressure_floor", &dem::Controls::pressure_floor},
    {"/controls/max_stretch", &dem::Controls::max_stretch},
    {"/controls/max_rotation", &dem::Controls::max_rotation},
    {"/controls/mass_scale", &dem::Controls::mass_scale},
    {"/controls/skin", &dem::Controls::skin},
};

struct MatrixField {
  const char* dataset;
  Eigen::Matrix2d dem::RveSnapshot::*member;
};
constexpr MatrixField kMatrixFields[] = {
    {"/packing/cell", &dem::RveSnapshot::cell},
    {"/packing/reference_cell", &dem::RveSnapshot::reference_cell},
    {"/packing/frame", &dem::RveSnapshot::frame},
};

struct ScalarField {
  const char* dataset;
  double dem::RveSnapshot::*member;
};
constexpr ScalarField kScalarFields[] = {
    {"/packing/initial_void_ratio", &dem::RveSnapshot::initial_void_ratio},
    {"/packing/permeability_coefficient", &dem::RveSnapshot::permeability_coefficient},
};

struct ParticleField {
  const char* dataset;
  std::vector<double> dem::RveSnapshot::*member;
};
constexpr ParticleField kParticleFields[] = {
    {"/particles/radius", &dem::RveSnapshot::radius},
    {"/particles/sx", &dem::RveSnapshot::sx},
    {"/particles/sy", &dem::RveSnapshot::sy},
    {"/particles/vx", &dem::RveSnapshot::vx},
    {"/particles/vy", &dem::RveSnapshot::vy},
    {"/particles/omega", &dem::RveSnapshot::omega},
    {"/particles/theta", &dem::RveSnapshot::theta},
};

struct ContactField {
  const char* dataset;
  double dem::ContactHistory::*member;
};
constexpr ContactField kContactFields[] = {
    {"/contacts/tangential_force", &dem::ContactHistory::tangential_force},
    {"/contacts/rolling_moment", &dem::ContactHistory::rolling_moment},
    {"/contacts/bond_strength", &dem::ContactHistory::bond_strength},
};

// Stored values of the ContactModel enum (the file's contract, not the
// enum's order).
constexpr std::int32_t kModelLinear = 0;
constexpr std::int32_t kModelHertzMindlin = 1;

// What makes a packing storable and restorable: valid material and
// controls, one value per particle in every particle array, and contact
// indices i < j inside the packing. (The rest, e.g. finiteness, is
// Rve::Create's to judge: the store keeps whatever state it is given.)
absl::Status CheckPacking(const dem::RveSnapshot& p) {
  if (absl::Status s = dem::Validate(p.material); !s.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("material: ", s.message()));
  }
  if (absl::Status s = dem::Validate(p.controls); !s.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("controls: ", s.message()));
  }
  if (p.material.model != dem::ContactModel::kLinear &&
      p.material.model != dem::ContactModel::kHertzMindlin) {
    return absl::InvalidArgumentError("material: unknown contact model");
  }
  if (p.material.name.find('\0') != std::string::npos) {
    return absl::InvalidArgumentError("material name contains a NUL byte");
  }
  const std::size_t n = p.radius.size();
  for (const ParticleField& f : kParticleFields) {
    if ((p.*f.member).size() != n) {
      return absl::InvalidArgumentError(absl::StrCat(
          "particle array ", f.dataset, " has ", (p.*f.member).size(), " values; radius has ", n));
    }
  }
  for (std::size_t k = 0; k < p.contacts.size(); ++k) {
    const dem::ContactHistory& c = p.contacts[k];
    if (c.i >= c.j || c.j >= n) {
      return absl::InvalidArgumentError(
          absl::StrCat("contact ", k, " has indices (", c.i, ", ", c.j, "); need i < j < ", n));
    }
  }
  return absl::OkStatus();
}

// Row-major 2×2 / 3×3 matrices, appended to `out`.
void AppendRowMajor(const Eigen::Matrix2d& m, std::vector<double>* out) {
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 2; ++c) out->push_back(m(r, c));
  }
}
void AppendRowMajor(const Eigen::Matrix3d& m, std::vector<double>* out) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out->push_back(m(r, c));
  }
}
template <int kN>
Eigen::Matrix<double, kN, kN> FromRowMajor(const double* v) {
  Eigen::Matrix<double, kN, kN> m;
  for (int r = 0; r < kN; ++r) {
    for (int c = 0; c < kN; ++c) m(r, c) = v[r * kN + c];
  }
  return m;
}

// Writes the packing part shared by both kinds of record, under `group`.
absl::Status WritePackings(h5::File& file, const std::string& group,
                           const std::vector<const dem::RveSnapshot*>& packings) {
  const auto at = [&group](const char* dataset) { return absl::StrCat(group, dataset); };
  const std::size_t n = packings.size();
  std::vector<std::string> names;
  std::vector<std::int32_t> models;
  names.reserve(n);
  models.reserve(n);
  for (const dem::RveSnapshot* p : packings) {
    names.push_back(p->material.name);
    models.push_back(p->material.model == dem::ContactModel::kHertzMindlin ? kModelHertzMindlin
                                                                           : kModelLinear);
  }
  RETURN_IF_ERROR(file.WriteStrings(at("/material/name"), names));
  RETURN_IF_ERROR(file.Write(at("/material/model"), Span(models)));

  std::vector<double> values;
  values.reserve(n * 4);
  for (const MaterialField& f : kMaterialFields) {
    values.clear();
    for (const dem::RveSnapshot* p : packings) values.push_back(p->material.*f.member);
    RETURN_IF_ERROR(file.Write(at(f.dataset), Span(values)));
  }
  for (const ControlsField& f : kControlsFields) {
    values.clear();
    for (const dem::RveSnapshot* p : packings) values.push_back(p->controls.*f.member);
    RETURN_IF_ERROR(file.Write(at(f.dataset), Span(values)));
  }
  std::vector<std::int64_t> integers;
  integers.reserve(n + 1);
  for (const dem::RveSnapshot* p : packings) integers.push_back(p->controls.min_steps);
  RETURN_IF_ERROR(file.Write(at("/controls/min_steps"), Span(integers)));

  for (const MatrixField& f : kMatrixFields) {
    values.clear();
    for (const dem::RveSnapshot* p : packings) AppendRowMajor(p->*f.member, &values);
    RETURN_IF_ERROR(file.Write(at(f.dataset), Span(values), 4));
  }
  for (const ScalarField& f : kScalarFields) {
    values.clear();
    for (const dem::RveSnapshot* p : packings) values.push_back(p->*f.member);
    RETURN_IF_ERROR(file.Write(at(f.dataset), Span(values)));
  }
  integers.clear();
  for (const dem::RveSnapshot* p : packings) integers.push_back(p->total_steps);
  RETURN_IF_ERROR(file.Write(at("/packing/total_steps"), Span(integers)));

  // CSR offsets: record k owns particles [offset[k], offset[k+1]).
  std::size_t num_particles = 0, num_contacts = 0;
  integers.assign(1, 0);
  for (const dem::RveSnapshot* p : packings) {
    num_particles += p->radius.size();
    integers.push_back(static_cast<std::int64_t>(num_particles));
  }
  RETURN_IF_ERROR(file.Write(at("/packing/particle_offset"), Span(integers)));
  integers.assign(1, 0);
  for (const dem::RveSnapshot* p : packings) {
    num_contacts += p->contacts.size();
    integers.push_back(static_cast<std::int64_t>(num_contacts));
  }
  RETURN_IF_ERROR(file.Write(at("/packing/contact_offset"), Span(integers)));

  // Particle and contact arrays: concatenated over records, one field at a
  // time (one large write per dataset; one field's worth of scratch memory).
  values.reserve(std::max(num_particles, num_contacts));
  for (const ParticleField& f : kParticleFields) {
    values.clear();
    for (const dem::RveSnapshot* p : packings) {
      const std::vector<double>& v = p->*f.member;
      values.insert(values.end(), v.begin(), v.end());
    }
    RETURN_IF_ERROR(file.Write(at(f.dataset), Span(values)));
  }
  std::vector<std::uint32_t> indices;
  indices.reserve(num_contacts);
  for (auto [dataset, member] : {std::pair{"/contacts/i", &dem::ContactHistory::i},
                                 std::pair{"/contacts/j", &dem::ContactHistory::j}}) {
    indices.clear();
    for (const dem::RveSnapshot* p : packings) {
      for (const dem::ContactHistory& c : p->contacts) indices.push_back(c.*member);
    }
    RETURN_IF_ERROR(file.Write(at(dataset), Span(indices)));
  }
  for (const ContactField& f : kContactFields) {
    values.clear();
    for (const dem::RveSnapshot* p : packings) {
      for (const dem::ContactHistory& c : p->contacts) values.push_back(c.*f.member);
    }
    RETURN_IF_ERROR(file.Write(at(f.dataset), Span(values)));
  }
  return absl::OkStatus();
}

// Reads the packing part shared by both kinds of record, from under
// `group`; `label(k)` names record k in messages.
absl::StatusOr<std::vector<dem::RveSnapshot>> ReadPackings(
    const h5::File& file, const std::string& group, std::size_t n,
    const std::function<std::string(std::size_t)>& label) {
  const auto at = [&group](const char* dataset) { return absl::StrCat(group, dataset); };
  std::vector<dem::RveSnapshot> packings(n);
  std::vector<std::string> names;
  RETURN_IF_ERROR(file.ReadStrings(at("/material/name"), n, &names));
  std::vector<std::int32_t> models;
  RETURN_IF_ERROR(file.Read(at("/material/model"), n, 0, &models));
  for (std::size_t k = 0; k < n; ++k) {
    packings[k].material.name = std::move(names[k]);
    switch (models[k]) {
      case kModelLinear:
        packings[k].material.model = dem::ContactModel::kLinear;
        break;
      case kModelHertzMindlin:
        packings[k].material.model = dem::ContactModel::kHertzMindlin;
        break;
      default:
        return absl::DataLossError(absl::StrCat(label(k), " of ", file.path(),
                                                ": unknown contact model ", models[k], " in ",
                                                at("/material/model"), ": file is corrupt"));
    }
  }
  std::vector<double> values;
  for (const MaterialField& f : kMaterialFields) {
    RETURN_IF_ERROR(file.Read(at(f.dataset), n, 0, &values));
    for (std::size_t k = 0; k < n; ++k) packings[k].material.*f.member = values[k];
  }
  for (const ControlsField& f : kControlsFields) {
    RETURN_IF_ERROR(file.Read(at(f.dataset), n, 0, &values));
    for (std::size_t k = 0; k < n; ++k) packings[k].controls.*f.member = values[k];
  }
  std::vector<std::int64_t> integers;
  RETURN_IF_ERROR(file.Read(at("/controls/min_steps"), n, 0, &integers));
  for (std::size_t k = 0; k < n; ++k) packings[k].controls.min_steps = integers[k];
  for (const MatrixField& f : kMatrixFields) {
    RETURN_IF_ERROR(file.Read(at(f.dataset), n, 4, &values));
    for (std::size_t k = 0; k < n; ++k) packings[k].*f.member = FromRowMajor<2>(&values[4 * k]);
  }
  for (const ScalarField& f : kScalarFields) {
    RETURN_IF_ERROR(file.Read(at(f.dataset), n, 0, &values));
    for (std::size_t k = 0; k < n; ++k) packings[k].*f.member = values[k];
  }
  RETURN_IF_ERROR(file.Read(at("/packing/total_steps"), n, 0, &integers));
  for (std::size_t k = 0; k < n; ++k) packings[k].total_steps = integers[k];

  std::vector<std::int64_t> particle_offset, contact_offset;
  RETURN_IF_ERROR(file.Read(at("/packing/particle_offset"), n + 1, 0, &particle_offset));
  RETURN_IF_ERROR(
      internal::CheckOffsets(particle_offset, at("/packing/particle_offset"), file.path()));
  RETURN_IF_ERROR(file.Read(at("/packing/contact_offset"), n + 1, 0, &contact_offset));
  RETURN_IF_ERROR(
      internal::CheckOffsets(contact_offset, at("/packing/contact_offset"), file.path()));
  // The last offset is the length of every particle (contact) dataset;
  // Read checks the datasets' shapes against it.
  const auto num_particles = static_cast<std::size_t>(particle_offset.back());
  const auto num_contacts = static_cast<std::size_t>(contact_offset.back());

  for (const ParticleField& f : kParticleFields) {
    RETURN_IF_ERROR(file.Read(at(f.dataset), num_particles, 0, &values));
    for (std::size_t k = 0; k < n; ++k) {
      (packings[k].*f.member)
          .assign(values.begin() + particle_offset[k], values.begin() + particle_offset[k + 1]);
    }
  }
  // All five contact columns first, then each record's contacts built in
  // one pass (one write per contact instead of five passes over them).
  std::vector<std::uint32_t> i_values, j_values;
  RETURN_IF_ERROR(file.Read(at("/contacts/i"), num_contacts, 0, &i_values));
  RETURN_IF_ERROR(file.Read(at("/contacts/j"), num_contacts, 0, &j_values));
  constexpr std::size_t kNumContactFields = std::size(kContactFields);
  std::vector<double> contact_values[kNumContactFields];
  for (std::size_t f = 0; f < kNumContactFields; ++f) {
    RETURN_IF_ERROR(file.Read(at(kContactFields[f].dataset), num_contacts, 0, &contact_values[f]));
  }
  for (std::size_t k = 0; k < n; ++k) {
    std::vector<dem::ContactHistory>& contacts = packings[k].contacts;
    const auto begin = static_cast<std::size_t>(contact_offset[k]);
    const auto end = static_cast<std::size_t>(contact_offset[k + 1]);
    contacts.reserve(end - begin);
    for (std::size_t m = begin; m < end; ++m) {
      dem::ContactHistory& c = contacts.emplace_back();
      c.i = i_values[m];
      c.j = j_values[m];
      for (std::size_t f = 0; f < kNumContactFields; ++f) {
        c.*kContactFields[f].member = contact_values[f][m];
      }
    }
  }
  for (std::size_t k = 0; k < n; ++k) {
    if (absl::Status s = CheckPacking(packings[k]); !s.ok()) {
      return absl::DataLossError(
          absl::StrCat(label(k), " of ", file.path(), " is invalid: ", s.message()));
    }
  }
  return packings;
}

std::string RveLabel(std::size_t k, const std::string& run_id, std::int64_t id) {
  return absl::StrCat("record ", k, " (run '", run_id, "', id ", id, ")");
}

std::string TemplateLabel(std::size_t k, const std::string& name) {
  return absl::StrCat("template ", k, " ('", name, "')");
}

// "read it with ReadRves" and the like, for a file of a known other kind.
std::string ReaderFor(absl::string_view kind) {
  if (kind == kKindRves) return "ReadRves";
  if (kind == kKindTemplates) return "ReadTemplates";
  if (kind == kKindSimulation) return "ReadSimCheckpoint";
  if (kind == internal::kKindResults) return "ReadResults";
  return "";
}

}  // namespace

// Declared in checkpoint.h: servers call it on start.
void RemoveStaleTemporaries(const std::string& path, bool own_too) {
  namespace fs = std::filesystem;
  const fs::path target(path);
  const std::string prefix = absl::StrCat(target.filename().string(), ".tmp-");
  const fs::path dir = target.parent_path().empty() ? fs::path(".") : target.parent_path();
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    int pid = 0;
    if (!absl::StartsWith(name, prefix) || !absl::SimpleAtoi(name.substr(prefix.size()), &pid) ||
        pid <= 0 || (pid == ::getpid() && !own_too)) {
      continue;
    }
    // kill(pid, 0) probes without signalling: ESRCH means no such process.
    std::error_code type_ec;
    const bool stale = pid == ::getpid() || (::kill(pid, 0) != 0 && errno == ESRCH);
    if (stale && it->is_regular_file(type_ec)) {
      std::error_code ignored;
      fs::remove(it->path(), ignored);
    }
  }
}

namespace internal {

std::mutex& StoreMutex() {
  static auto* mutex = new std::mutex();
  return *mutex;
}

bool HasNul(const std::string& s) { return s.find('\0') != std::string::npos; }

std::string UtcNow() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  char text[32] = "";
  if (gmtime_r(&now, &tm) == nullptr ||
      std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &tm) == 0) {
    return "";
  }
  return text;
}

void SyncPath(const std::string& path, int flags) {
  const int fd = ::open(path.c_str(), flags | O_CLOEXEC);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

absl::Status CheckOffsets(const std::vector<std::int64_t>& offsets, const std::string& dataset,
                          const std::string& path) {
  if (offsets.empty() || offsets[0] != 0) {
    return absl::DataLossError(
        absl::StrCat("dataset ", dataset, " of ", path, " must start at 0: file is corrupt"));
  }
  for (std::size_t k = 1; k < offsets.size(); ++k) {
    if (offsets[k] < offsets[k - 1]) {
      return absl::DataLossError(absl::StrCat("dataset ", dataset, " of ", path,
                                              " decreases at entry ", k, " (", offsets[k - 1],
                                              " > ", offsets[k], "): file is corrupt"));
    }
  }
  return absl::OkStatus();
}

absl::Status CheckRveRecords(const std::string& path, std::span<const RveRecord> rves) {
  for (std::size_t k = 0; k < rves.size(); ++k) {
    const RveRecord& r = rves[k];
    absl::Status s = CheckPacking(r.packing);
    if (s.ok() && HasNul(r.run_id)) s = absl::InvalidArgumentError("run_id contains a NUL byte");
    if (!s.ok()) {
      return absl::InvalidArgumentError(absl::StrCat(
          "cannot write ", path, ": ", RveLabel(k, r.run_id, r.id), ": ", s.message()));
    }
  }
  return absl::OkStatus();
}

absl::Status CheckTemplateRecords(const std::string& path,
                                  std::span<const TemplateRecord> templates) {
  for (std::size_t k = 0; k < templates.size(); ++k) {
    const TemplateRecord& t = templates[k];
    absl::Status s = CheckPacking(t.packing);
    if (s.ok() && (HasNul(t.name) || HasNul(t.description))) {
      s = absl::InvalidArgumentError("name or description contains a NUL byte");
    }
    if (!s.ok()) {
      return absl::InvalidArgumentError(
          absl::StrCat("cannot write ", path, ": ", TemplateLabel(k, t.name), ": ", s.message()));
    }
  }
  return absl::OkStatus();
}

absl::Status WriteRveRecords(h5::File& file, const std::string& group,
                             std::span<const RveRecord> rves) {
  std::vector<const dem::RveSnapshot*> packings;
  std::vector<std::string> run_ids;
  std::vector<std::int64_t> ids, steps;
  std::vector<double> delta_f;
  packings.reserve(rves.size());
  run_ids.reserve(rves.size());
  delta_f.reserve(9 * rves.size());
  for (const RveRecord& r : rves) {
    packings.push_back(&r.packing);
    run_ids.push_back(r.run_id);
    ids.push_back(r.id);
    steps.push_back(r.step);
    AppendRowMajor(r.last_delta_f, &delta_f);
  }
  RETURN_IF_ERROR(file.WriteStrings(absl::StrCat(group, "/records/run_id"), run_ids));
  RETURN_IF_ERROR(file.Write(absl::StrCat(group, "/records/id"), Span(ids)));
  RETURN_IF_ERROR(file.Write(absl::StrCat(group, "/records/step"), Span(steps)));
  RETURN_IF_ERROR(file.Write(absl::StrCat(group, "/records/last_delta_f"), Span(delta_f), 9));
  return WritePackings(file, group, packings);
}

absl::StatusOr<std::vector<RveRecord>> ReadRveRecords(const h5::File& file,
                                                      const std::string& group, std::size_t n) {
  std::vector<std::string> run_ids;
  std::vector<std::int64_t> ids, steps;
  std::vector<double> delta_f;
  RETURN_IF_ERROR(file.ReadStrings(absl::StrCat(group, "/records/run_id"), n, &run_ids));
  RETURN_IF_ERROR(file.Read(absl::StrCat(group, "/records/id"), n, 0, &ids));
  RETURN_IF_ERROR(file.Read(absl::StrCat(group, "/records/step"), n, 0, &steps));
  RETURN_IF_ERROR(file.Read(absl::StrCat(group, "/records/last_delta_f"), n, 9, &delta_f));
  ASSIGN_OR_RETURN(
      std::vector<dem::RveSnapshot> packings,
      ReadPackings(file, group, n, [&](std::size_t k) { return RveLabel(k, run_ids[k], ids[k]); }));
  std::vector<RveRecord> rves(n);
  for (std::size_t k = 0; k < n; ++k) {
    rves[k].run_id = std::move(run_ids[k]);
    rves[k].id = ids[k];
    rves[k].step = steps[k];
    rves[k].last_delta_f = FromRowMajor<3>(&delta_f[9 * k]);
    rves[k].packing = std::move((packings)[k]);
  }
  return rves;
}

absl::Status WriteTemplateRecords(h5::File& file, const std::string& group,
                                  std::span<const TemplateRecord> templates) {
  std::vector<const dem::RveSnapshot*> packings;
  std::vector<std::string> names, descriptions;
  packings.reserve(templates.size());
  names.reserve(templates.size());
  descriptions.reserve(templates.size());
  for (const TemplateRecord& t : templates) {
    packings.push_back(&t.packing);
    names.push_back(t.name);
    descriptions.push_back(t.description);
  }
  RETURN_IF_ERROR(file.WriteStrings(absl::StrCat(group, "/records/name"), names));
  RETURN_IF_ERROR(file.WriteStrings(absl::StrCat(group, "/records/description"), descriptions));
  return WritePackings(file, group, packings);
}

absl::StatusOr<std::vector<TemplateRecord>> ReadTemplateRecords(const h5::File& file,
                                                                const std::string& group,
                                                                std::size_t n) {
  std::vector<std::string> names, descriptions;
  RETURN_IF_ERROR(file.ReadStrings(absl::StrCat(group, "/records/name"), n, &names));
  RETURN_IF_ERROR(file.ReadStrings(absl::StrCat(group, "/records/description"), n, &descriptions));
  ASSIGN_OR_RETURN(
      std::vector<dem::RveSnapshot> packings,
      ReadPackings(file, group, n, [&](std::size_t k) { return TemplateLabel(k, names[k]); }));
  std::vector<TemplateRecord> templates(n);
  for (std::size_t k = 0; k < n; ++k) {
    templates[k].name = std::move(names[k]);
    templates[k].description = std::move(descriptions[k]);
    templates[k].packing = std::move((packings)[k]);
  }
  return templates;
}

absl::Status WriteAtomically(const std::string& path, const char* kind,
                             std::span<const std::pair<const char*, std::int64_t>> counts,
                             const FileInfo& info,
                             const std::function<absl::Status(h5::File&)>& body) {
  if (HasNul(info.created_by) || HasNul(info.created_at)) {
    return absl::InvalidArgumentError("FileInfo strings must not contain NUL bytes");
  }
  // The rename below replaces whatever has the name: run as root it had
  // made /dev/full (rve_cli checkpoint --out=/dev/full) a regular file. Only
  // a regular file is replaced; a link is not followed or replaced either.
  if (struct stat st{}; ::lstat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {
    return absl::InvalidArgumentError(
        absl::StrCat("cannot write ", path,
                     ": it exists and is not a regular file (a directory, device or "
                     "link); nothing was written"));
  }
  RemoveStaleTemporaries(path);
  const std::string temp = absl::StrCat(path, ".tmp-", ::getpid());
  // Create the temporary file ourselves first: errno tells precisely why a
  // directory is unusable (HDF5 only says "unable to open file"), and a
  // pre-existing directory of that name is never removed below.
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    return absl::ErrnoToStatus(
        errno, absl::StrCat("cannot write ", path, ": cannot create temporary file ", temp));
  }
  ::close(fd);

  absl::Status status = [&]() -> absl::Status {
    ASSIGN_OR_RETURN(h5::File file, h5::File::Create(temp));
    RETURN_IF_ERROR(file.WriteAttribute<std::int32_t>("format_version", kFormatVersion));
    RETURN_IF_ERROR(file.WriteStringAttribute("kind", kind));
    RETURN_IF_ERROR(file.WriteStringAttribute("created_by", info.created_by));
    RETURN_IF_ERROR(file.WriteStringAttribute(
        "created_at", info.created_at.empty() ? UtcNow() : info.created_at));
    for (const auto& [name, value] : counts) {
      RETURN_IF_ERROR(file.WriteAttribute<std::int64_t>(name, value));
    }
    RETURN_IF_ERROR(file.WriteStringAttribute("engine", kEngine));
    RETURN_IF_ERROR(body(file));
    RETURN_IF_ERROR(file.Close());
    // Data before name: after a crash `path` holds the old or the new file,
    // never a renamed but unwritten one.
    SyncPath(temp, O_RDONLY);
    if (std::rename(temp.c_str(), path.c_str()) != 0) {
      return absl::ErrnoToStatus(errno, absl::StrCat("cannot rename ", temp, " to ", path));
    }
    std::filesystem::path dir = std::filesystem::path(path).parent_path();
    SyncPath(dir.empty() ? "." : dir.string(), O_RDONLY | O_DIRECTORY);
    return absl::OkStatus();
  }();
  if (!status.ok()) {
    std::error_code ignored;
    std::filesystem::remove(temp, ignored);
    return absl::Status(status.code(), absl::StrCat("writing ", path, ": ", status.message()));
  }
  return absl::OkStatus();
}

absl::StatusOr<h5::File> OpenStore(const std::string& path, const char* kind, FileInfo* info) {
  h5::SilenceErrorPrinting();
  // open(2) first: its errno distinguishes a missing file from an
  // unreadable one, which HDF5 reports alike.
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return absl::ErrnoToStatus(errno, absl::StrCat("cannot open ", path));
  struct stat st {};
  const bool regular = ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode);
  ::close(fd);
  if (!regular) return absl::InvalidArgumentError(absl::StrCat(path, " is not a regular file"));

  ASSIGN_OR_RETURN(h5::File file, h5::File::Open(path));
  absl::StatusOr<std::string> file_kind = file.ReadStringAttribute("kind");
  if (absl::IsNotFound(file_kind.status())) {
    return absl::InvalidArgumentError(
        absl::StrCat(path, " is not an RVEHub store file (no 'kind' attribute)"));
  }
  if (!file_kind.ok()) return file_kind.status();
  ASSIGN_OR_RETURN(std::int64_t version, file.ReadIntAttribute("format_version"));
  if (version > kFormatVersion) {
    return absl::FailedPreconditionError(absl::StrCat(
        path, " has format_version ", version, ", newer than this build reads (format_version ",
        kFormatVersion, "): read it with a newer RVEHub"));
  }
  if (version < 1) {
    return absl::DataLossError(
        absl::StrCat(path, " has an invalid format_version ", version, ": file is corrupt"));
  }
  if (*file_kind != kind) {
    const std::string reader = ReaderFor(*file_kind);
    return absl::InvalidArgumentError(
        absl::StrCat(path, " holds ", reader.empty() ? "unknown kind " : "", "'", *file_kind,
                     "', not '", kind, "'", reader.empty() ? "" : ": read it with ", reader));
  }
  if (info != nullptr) {
    ASSIGN_OR_RETURN(std::string created_by, file.ReadStringAttribute("created_by"));
    ASSIGN_OR_RETURN(std::string created_at, file.ReadStringAttribute("created_at"));
    info->created_by = std::move(created_by);
    info->created_at = std::move(created_at);
    info->format_version = static_cast<std::int32_t>(version);
  }
  return file;
}

absl::StatusOr<std::size_t> ReadCount(const h5::File& file, const char* attribute) {
  ASSIGN_OR_RETURN(std::int64_t n, file.ReadIntAttribute(attribute));
  ASSIGN_OR_RETURN(std::uint64_t size, file.Size());
  // Every record takes well over a byte; the bound keeps a corrupt count
  // from allocating absurd amounts of memory.
  if (n < 0 || static_cast<std::uint64_t>(n) > size) {
    return absl::DataLossError(
        absl::StrCat(file.path(), " has an invalid ", attribute, " ", n, ": file is corrupt"));
  }
  return static_cast<std::size_t>(n);
}

}  // namespace internal

}  // namespace rvehub::store
