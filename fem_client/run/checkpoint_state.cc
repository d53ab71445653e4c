#include "fem_client/run/checkpoint_state.h"

#include <utility>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"

namespace rvehub::fem {
namespace {

void PutMatrix(const Eigen::Matrix3d& m, std::vector<double>& out) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out.push_back(m(r, c));
  }
}

Eigen::Matrix3d GetMatrix(const double* v) {
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m(r, c) = v[3 * r + c];
  }
  return m;
}

void PutTangent(const Tangent& d, std::vector<double>& out) {
  out.insert(out.end(), d.data(), d.data() + d.size());
}

Tangent GetTangent(const double* v) { return Eigen::Map<const Tangent>(v); }

std::vector<double> FromVector(const Eigen::VectorXd& v) {
  return std::vector<double>(v.data(), v.data() + v.size());
}

Eigen::VectorXd ToVector(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

// The array under `key`, of `per` values per item: its item count.
absl::StatusOr<std::size_t> Items(const NamedDoubles& doubles, const std::string& key,
                                  std::size_t per) {
  auto it = doubles.find(key);
  if (it == doubles.end()) {
    return absl::InvalidArgumentError(absl::StrCat("checkpoint state: '", key, "' is missing"));
  }
  if (it->second.size() % per != 0) {
    return absl::InvalidArgumentError(absl::StrCat("checkpoint state: '", key, "' has ",
                                                   it->second.size(), " values, not a multiple of ",
                                                   per));
  }
  return it->second.size() / per;
}

absl::Status Expect(const std::string& key, std::size_t got, std::size_t want, const char* what) {
  if (got == want) return absl::OkStatus();
  return absl::InvalidArgumentError(
      absl::StrCat("checkpoint state: '", key, "' holds ", got, " ", what, ", not ", want));
}

absl::StatusOr<std::int64_t> Scalar(const NamedInts& ints, const std::string& key) {
  auto it = ints.find(key);
  if (it == ints.end() || it->second.size() != 1) {
    return absl::InvalidArgumentError(
        absl::StrCat("checkpoint state: '", key, "' is missing or not one value"));
  }
  return it->second[0];
}

}  // namespace

void PutRunState(const RunState& s, NamedDoubles& doubles, NamedInts& ints) {
  const SolverState& v = s.solver;
  ints["steps"] = {v.steps};
  ints["committed_step"] = {s.committed_step};
  std::vector<double>& nodes = doubles["nodes"];
  nodes.clear();
  for (const Eigen::Vector2d& x : v.nodes) nodes.insert(nodes.end(), {x.x(), x.y()});
  doubles["displacement"] = FromVector(v.displacement);
  std::vector<double>& stress = doubles["stress"];
  std::vector<double>& tangent = doubles["tangent"];
  std::vector<std::int64_t>& has_tangent = ints["has_tangent"];
  stress.clear();
  tangent.clear();
  has_tangent.clear();
  for (const PointResponse& r : v.responses) {
    PutMatrix(r.stress, stress);
    has_tangent.push_back(r.tangent.has_value() ? 1 : 0);
    if (r.tangent.has_value()) PutTangent(*r.tangent, tangent);
  }
  doubles["f_int"] = FromVector(v.f_int);
  doubles["f_ext"] = FromVector(v.f_ext);
  doubles["residual"] = FromVector(v.residual);
  doubles["platen_force"] = v.platen_force;
  std::vector<double>& initial = doubles["initial_tangents"];
  initial.clear();
  for (const Tangent& d : v.initial_tangents) PutTangent(d, initial);
  doubles["last_rate"] = FromVector(v.last_rate);
  // The second gradient's fields, present only when the run has one.
  if (!v.second_gradient.double_stress.empty()) {
    std::vector<double>& ds = doubles["double_stress"];
    ds.clear();
    for (const DoubleStress& d : v.second_gradient.double_stress) {
      ds.insert(ds.end(), d.data(), d.data() + d.size());
    }
    doubles["multiplier"] = FromVector(v.second_gradient.multiplier);
    doubles["micro"] = FromVector(v.second_gradient.micro);
  }
  std::vector<double>& rs = doubles["rve_stress"];
  std::vector<double>& re = doubles["rve_void_ratio"];
  std::vector<double>& rz = doubles["rve_coordination"];
  std::vector<double>& rf = doubles["rve_fabric_anisotropy"];
  rs.clear();
  re.clear();
  rz.clear();
  rf.clear();
  for (const dem::RveState& r : s.rves) {
    PutMatrix(r.stress, rs);
    re.push_back(r.void_ratio);
    rz.push_back(r.coordination);
    rf.push_back(r.fabric_anisotropy);
  }
}

absl::StatusOr<RunState> GetRunState(const NamedDoubles& doubles, const NamedInts& ints) {
  RunState s;
  SolverState& v = s.solver;
  absl::StatusOr<std::int64_t> steps = Scalar(ints, "steps");
  if (!steps.ok()) return steps.status();
  if (*steps < 0 || *steps > (std::int64_t{1} << 30)) {
    return absl::InvalidArgumentError(
        absl::StrCat("checkpoint state: 'steps' is ", *steps, ", not in [0, 2^30]"));
  }
  v.steps = static_cast<int>(*steps);
  absl::StatusOr<std::int64_t> committed = Scalar(ints, "committed_step");
  if (!committed.ok()) return committed.status();
  if (*committed < *steps || *committed > (std::int64_t{1} << 50)) {
    return absl::InvalidArgumentError(absl::StrCat("checkpoint state: 'committed_step' is ",
                                                   *committed, ", not in [steps, 2^50]"));
  }
  s.committed_step = *committed;

  absl::StatusOr<std::size_t> nodes = Items(doubles, "nodes", 2);
  if (!nodes.ok()) return nodes.status();
  const std::vector<double>& x = doubles.at("nodes");
  for (std::size_t a = 0; a < *nodes; ++a) v.nodes.emplace_back(x[2 * a], x[2 * a + 1]);
  for (const char* key : {"displacement", "f_int", "f_ext", "residual"}) {
    absl::StatusOr<std::size_t> n = Items(doubles, key, 1);
    if (!n.ok()) return n.status();
  }
  v.displacement = ToVector(doubles.at("displacement"));
  v.f_int = ToVector(doubles.at("f_int"));
  v.f_ext = ToVector(doubles.at("f_ext"));
  v.residual = ToVector(doubles.at("residual"));

  absl::StatusOr<std::size_t> points = Items(doubles, "stress", 9);
  if (!points.ok()) return points.status();
  auto has = ints.find("has_tangent");
  if (has == ints.end()) {
    return absl::InvalidArgumentError("checkpoint state: 'has_tangent' is missing");
  }
  if (absl::Status e = Expect("has_tangent", has->second.size(), *points, "Gauss points");
      !e.ok()) {
    return e;
  }
  std::size_t with_tangent = 0;
  for (std::int64_t h : has->second) with_tangent += h != 0 ? 1 : 0;
  absl::StatusOr<std::size_t> tangents = Items(doubles, "tangent", 81);
  if (!tangents.ok()) return tangents.status();
  if (absl::Status e = Expect("tangent", *tangents, with_tangent, "tangents"); !e.ok()) return e;
  const std::vector<double>& sv = doubles.at("stress");
  const std::vector<double>& tv = doubles.at("tangent");
  std::size_t t = 0;
  for (std::size_t p = 0; p < *points; ++p) {
    PointResponse r;
    r.stress = GetMatrix(&sv[9 * p]);
    if (has->second[p] != 0) r.tangent = GetTangent(&tv[81 * t++]);
    v.responses.push_back(std::move(r));
  }
  absl::StatusOr<std::size_t> platens = Items(doubles, "platen_force", 1);
  if (!platens.ok()) return platens.status();
  v.platen_force = doubles.at("platen_force");
  absl::StatusOr<std::size_t> initial = Items(doubles, "initial_tangents", 81);
  if (!initial.ok()) return initial.status();
  const std::vector<double>& iv = doubles.at("initial_tangents");
  for (std::size_t p = 0; p < *initial; ++p) v.initial_tangents.push_back(GetTangent(&iv[81 * p]));
  // Absent from checkpoints of runs that had no predictor to keep.
  if (auto it = doubles.find("last_rate"); it != doubles.end()) v.last_rate = ToVector(it->second);
  if (doubles.contains("double_stress")) {
    absl::StatusOr<std::size_t> n = Items(doubles, "double_stress", 8);
    if (!n.ok()) return n.status();
    const std::vector<double>& dv = doubles.at("double_stress");
    for (std::size_t p = 0; p < *n; ++p) {
      v.second_gradient.double_stress.push_back(Eigen::Map<const DoubleStress>(&dv[8 * p]));
    }
    for (const char* key : {"multiplier", "micro"}) {
      absl::StatusOr<std::size_t> m = Items(doubles, key, 1);
      if (!m.ok()) return m.status();
    }
    v.second_gradient.multiplier = ToVector(doubles.at("multiplier"));
    v.second_gradient.micro = ToVector(doubles.at("micro"));
  }

  absl::StatusOr<std::size_t> rves = Items(doubles, "rve_stress", 9);
  if (!rves.ok()) return rves.status();
  if (absl::Status e = Expect("rve_stress", *rves, *points, "Gauss points"); !e.ok()) return e;
  for (const char* key : {"rve_void_ratio", "rve_coordination", "rve_fabric_anisotropy"}) {
    absl::StatusOr<std::size_t> n = Items(doubles, key, 1);
    if (!n.ok()) return n.status();
    if (absl::Status e = Expect(key, *n, *points, "Gauss points"); !e.ok()) return e;
  }
  const std::vector<double>& rs = doubles.at("rve_stress");
  for (std::size_t p = 0; p < *rves; ++p) {
    dem::RveState r;
    r.stress = GetMatrix(&rs[9 * p]);
    r.void_ratio = doubles.at("rve_void_ratio")[p];
    r.coordination = doubles.at("rve_coordination")[p];
    r.fabric_anisotropy = doubles.at("rve_fabric_anisotropy")[p];
    s.rves.push_back(std::move(r));
  }
  return s;
}

}  // namespace rvehub::fem
