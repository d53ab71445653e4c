#include "mpm_client/core/solver_checkpoint.h"

#include <Eigen/Dense>
#include <cmath>
#include <cstddef>
#include <utility>

#include "absl/strings/str_cat.h"
#include "mpm_client/core/shape.h"
#include "mpm_client/core/two_phase_solver.h"
#include "rve_server/common/status_macros.h"

namespace rvehub::mpm {
namespace {

using Eigen::Vector2d;

// The array `key` of `map`, InvalidArgument where it is missing or does
// not have `size` values.
template <typename T>
absl::StatusOr<const std::vector<T>*> Field(const std::map<std::string, std::vector<T>>& map,
                                            const std::string& key, std::size_t size) {
  const auto it = map.find(key);
  if (it == map.end()) return absl::InvalidArgumentError(absl::StrCat("state lacks ", key));
  if (it->second.size() != size) {
    return absl::InvalidArgumentError(
        absl::StrCat("state field ", key, " has ", it->second.size(), " values, expected ", size));
  }
  return &it->second;
}

}  // namespace

void ExportSolverState(const Solver& solver, std::map<std::string, std::vector<double>>& doubles,
                       std::map<std::string, std::vector<std::int64_t>>& ints) {
  // The two-phase scheme carries the water's state too.
  const auto* two_phase = dynamic_cast<const TwoPhaseSolver*>(&solver);
  const MaterialPoints& mp = solver.points();
  const std::size_t n = mp.size(), nl = mp.loads.size();
  auto put = [&](const std::string& key, std::size_t width, auto&& get) {
    std::vector<double>& out = doubles[key];
    out.clear();
    out.reserve(n * width);
    for (std::size_t p = 0; p < n; ++p) get(p, out);
  };
  auto vec2 = [](const Vector2d& v, std::vector<double>& out) {
    out.push_back(v.x());
    out.push_back(v.y());
  };
  auto mat = [](const auto& m, std::vector<double>& out) {
    for (int r = 0; r < m.rows(); ++r) {
      for (int c = 0; c < m.cols(); ++c) out.push_back(m(r, c));
    }
  };
  doubles["time"] = {solver.time()};
  doubles["dt"] = {solver.dt()};
  put("position", 2, [&](std::size_t p, auto& o) { vec2(mp.position[p], o); });
  put("velocity", 2, [&](std::size_t p, auto& o) { vec2(mp.velocity[p], o); });
  put("half_size0", 2, [&](std::size_t p, auto& o) { vec2(mp.half_size0[p], o); });
  put("mass", 1, [&](std::size_t p, auto& o) { o.push_back(mp.mass[p]); });
  put("volume", 1, [&](std::size_t p, auto& o) { o.push_back(mp.volume[p]); });
  put("volume0", 1, [&](std::size_t p, auto& o) { o.push_back(mp.volume0[p]); });
  put("deformation_gradient", 4, [&](std::size_t p, auto& o) { mat(mp.F[p], o); });
  put("stress", 9, [&](std::size_t p, auto& o) { mat(mp.stress[p], o); });
  put("response_stress", 9, [&](std::size_t p, auto& o) { mat(mp.response[p].stress, o); });
  put("void_ratio", 1, [&](std::size_t p, auto& o) { o.push_back(mp.response[p].void_ratio); });
  put("fabric_anisotropy", 1,
      [&](std::size_t p, auto& o) { o.push_back(mp.response[p].fabric_anisotropy); });
  put("mean_rotation", 1,
      [&](std::size_t p, auto& o) { o.push_back(mp.response[p].mean_rotation); });
  put("coordination", 1, [&](std::size_t p, auto& o) { o.push_back(mp.response[p].coordination); });
  put("permeability", 1, [&](std::size_t p, auto& o) { o.push_back(mp.response[p].permeability); });
  if (two_phase != nullptr) {
    put("fluid_velocity", 2, [&](std::size_t p, auto& o) { vec2(mp.fluid_velocity[p], o); });
    put("pore_pressure", 1, [&](std::size_t p, auto& o) { o.push_back(mp.pore_pressure[p]); });
    put("porosity0", 1, [&](std::size_t p, auto& o) { o.push_back(mp.porosity0[p]); });
    put("position0", 2, [&](std::size_t p, auto& o) { vec2(mp.position0[p], o); });
    put("vertical_stress0", 1,
        [&](std::size_t p, auto& o) { o.push_back(mp.vertical_stress0[p]); });
    doubles["node_pressure"] = two_phase->node_pressure();
  }
  std::vector<double>& traction = doubles["load_traction"];
  std::vector<double>& length0 = doubles["load_length0"];
  std::vector<double>& ramp = doubles["load_ramp_time"];
  std::vector<std::int64_t>& point = ints["load_point"];
  std::vector<std::int64_t>& axis = ints["load_normal_axis"];
  std::vector<std::int64_t>& sign = ints["load_normal_sign"];
  std::vector<std::int64_t>& source = ints["load_source"];
  traction.clear(), length0.clear(), ramp.clear(), point.clear(), axis.clear(), sign.clear();
  source.clear();
  for (std::size_t k = 0; k < nl; ++k) {
    const SurfaceLoad& load = mp.loads[k];
    vec2(load.traction, traction);
    length0.push_back(load.length0);
    ramp.push_back(load.ramp_time);
    point.push_back(load.point);
    axis.push_back(load.normal_axis);
    sign.push_back(load.normal_sign);
    source.push_back(load.source);
  }
  std::vector<double>& reactions = doubles["reactions"];
  reactions.clear();
  for (const Vector2d& r : solver.Reactions()) vec2(r, reactions);
  ints["step"] = {solver.step()};
  ints["region"].assign(mp.region.begin(), mp.region.end());
}

absl::Status ImportSolverState(Solver& solver,
                               const std::map<std::string, std::vector<double>>& doubles,
                               const std::map<std::string, std::vector<std::int64_t>>& ints) {
  auto* two_phase = dynamic_cast<TwoPhaseSolver*>(&solver);
  const bool saturated = two_phase != nullptr;
  const auto mass_it = doubles.find("mass");
  const auto load_it = ints.find("load_point");
  if (mass_it == doubles.end() || load_it == ints.end()) {
    return absl::InvalidArgumentError("state lacks mass or load_point");
  }
  const std::size_t n = mass_it->second.size(), nl = load_it->second.size();
  // Fetch every field first so that a bad state changes nothing.
  std::map<std::string, const std::vector<double>*> d;
  const std::pair<const char*, std::size_t> double_fields[] = {
      {"time", 1},
      {"dt", 1},
      {"position", 2 * n},
      {"velocity", 2 * n},
      {"half_size0", 2 * n},
      {"mass", n},
      {"volume", n},
      {"volume0", n},
      {"deformation_gradient", 4 * n},
      {"stress", 9 * n},
      {"response_stress", 9 * n},
      {"void_ratio", n},
      {"fabric_anisotropy", n},
      {"mean_rotation", n},
      {"coordination", n},
      {"permeability", n},
      {"load_traction", 2 * nl},
      {"load_length0", nl},
      {"load_ramp_time", nl},
      {"reactions", 2 * solver.Reactions().size()}};
  for (const auto& [key, size] : double_fields) {
    ASSIGN_OR_RETURN(const std::vector<double>* f, Field(doubles, key, size));
    d[key] = f;
  }
  if (saturated) {
    for (const auto& [key, size] : {std::pair{"fluid_velocity", 2 * n},
                                    {"pore_pressure", n},
                                    {"porosity0", n},
                                    {"position0", 2 * n},
                                    {"vertical_stress0", n}}) {
      ASSIGN_OR_RETURN(const std::vector<double>* f, Field(doubles, key, size));
      d[key] = f;
    }
  }
  std::map<std::string, const std::vector<std::int64_t>*> i;
  const std::pair<const char*, std::size_t> int_fields[] = {{"step", 1},
                                                            {"region", n},
                                                            {"load_point", nl},
                                                            {"load_normal_axis", nl},
                                                            {"load_normal_sign", nl}};
  for (const auto& [key, size] : int_fields) {
    ASSIGN_OR_RETURN(const std::vector<std::int64_t>* f, Field(ints, key, size));
    i[key] = f;
  }
  const std::vector<std::int64_t>* source = nullptr;
  if (ints.contains("load_source")) {
    ASSIGN_OR_RETURN(source, Field(ints, "load_source", nl));
  }
  MaterialPoints mp;
  mp.Resize(n);
  auto vec2 = [](const std::vector<double>& v, std::size_t p) {
    return Vector2d(v[2 * p], v[2 * p + 1]);
  };
  auto mat = [](auto& m, const std::vector<double>& v, std::size_t p) {
    const std::size_t size = m.rows() * m.cols();
    for (int r = 0; r < m.rows(); ++r) {
      for (int c = 0; c < m.cols(); ++c) m(r, c) = v[size * p + m.cols() * r + c];
    }
  };
  for (std::size_t p = 0; p < n; ++p) {
    mp.position[p] = vec2(*d["position"], p);
    mp.velocity[p] = vec2(*d["velocity"], p);
    mp.half_size0[p] = vec2(*d["half_size0"], p);
    mp.mass[p] = (*d["mass"])[p];
    mp.volume[p] = (*d["volume"])[p];
    mp.volume0[p] = (*d["volume0"])[p];
    mat(mp.F[p], *d["deformation_gradient"], p);
    mat(mp.stress[p], *d["stress"], p);
    PointResponse& r = mp.response[p];
    mat(r.stress, *d["response_stress"], p);
    r.void_ratio = (*d["void_ratio"])[p];
    r.fabric_anisotropy = (*d["fabric_anisotropy"])[p];
    r.mean_rotation = (*d["mean_rotation"])[p];
    r.coordination = (*d["coordination"])[p];
    r.permeability = (*d["permeability"])[p];
    mp.region[p] = static_cast<std::int32_t>((*i["region"])[p]);
    if (saturated) {
      mp.fluid_velocity[p] = vec2(*d["fluid_velocity"], p);
      mp.pore_pressure[p] = (*d["pore_pressure"])[p];
      mp.porosity0[p] = (*d["porosity0"])[p];
      mp.position0[p] = vec2(*d["position0"], p);
      mp.vertical_stress0[p] = (*d["vertical_stress0"])[p];
      if (!(mp.porosity0[p] > 0.0 && mp.porosity0[p] < 1.0)) {
        return absl::InvalidArgumentError(
            absl::StrCat("state porosity0[", p, "] = ", mp.porosity0[p], " is not in (0, 1)"));
      }
    }
  }
  mp.loads.resize(nl);
  for (std::size_t k = 0; k < nl; ++k) {
    SurfaceLoad& load = mp.loads[k];
    const std::int64_t point = (*i["load_point"])[k];
    if (point < 0 || static_cast<std::size_t>(point) >= n) {
      return absl::InvalidArgumentError(absl::StrCat("state load ", k, " names point ", point));
    }
    load.point = static_cast<std::int32_t>(point);
    load.traction = vec2(*d["load_traction"], k);
    load.length0 = (*d["load_length0"])[k];
    load.ramp_time = (*d["load_ramp_time"])[k];
    load.normal_axis = static_cast<int>((*i["load_normal_axis"])[k]);
    load.normal_sign = static_cast<int>((*i["load_normal_sign"])[k]);
    // States written before load histories existed have no sources.
    const std::int64_t from = source == nullptr ? -1 : (*source)[k];
    if (from < -1 || from >= static_cast<std::int64_t>(solver.traction_count())) {
      return absl::InvalidArgumentError(absl::StrCat("state load ", k, " names traction ", from));
    }
    load.source = static_cast<std::int32_t>(from);
    if ((load.normal_axis != 0 && load.normal_axis != 1) ||
        (load.normal_sign != 1 && load.normal_sign != -1)) {
      return absl::InvalidArgumentError(absl::StrCat("state load ", k, " has a bad normal"));
    }
  }
  const double time = (*d["time"])[0], dt = (*d["dt"])[0];
  const std::int64_t step = (*i["step"])[0];
  if (!(time >= 0.0 && std::isfinite(time)) || !(dt >= 0.0 && std::isfinite(dt)) || step < 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "state time ", time, " s, dt ", dt, " s and step ", step, " must be finite and >= 0"));
  }
  std::vector<double> node_pressure;
  if (saturated) {
    ASSIGN_OR_RETURN(
        const std::vector<double>* f,
        Field(doubles, "node_pressure", static_cast<std::size_t>(NodeCount(solver.grid()))));
    node_pressure = *f;
  }
  std::vector<Vector2d> reactions(solver.Reactions().size());
  for (std::size_t k = 0; k < reactions.size(); ++k) reactions[k] = vec2(*d["reactions"], k);
  RETURN_IF_ERROR(solver.Restore(std::move(mp), time, dt, step, std::move(reactions)));
  if (saturated) two_phase->set_node_pressure(std::move(node_pressure));
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<Solver>> SolverFromState(
    const CaseSpec& spec, const std::map<std::string, std::vector<double>>& doubles,
    const std::map<std::string, std::vector<std::int64_t>>& ints, StressModel* model) {
  ASSIGN_OR_RETURN(std::unique_ptr<Solver> solver, Solver::ForCase(spec, model));
  RETURN_IF_ERROR(ImportSolverState(*solver, doubles, ints));
  return solver;
}

}  // namespace rvehub::mpm
