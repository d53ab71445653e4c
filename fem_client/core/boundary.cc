#include "fem_client/core/boundary.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace rvehub::fem {
namespace {

const char* AxisName(int dof) { return dof == 0 ? "x" : "y"; }

absl::Status CheckPressures(int nodes, const Boundary& boundary) {
  for (std::size_t k = 0; k < boundary.pressures.size(); ++k) {
    const PressureLoad& load = boundary.pressures[k];
    if (!std::isfinite(load.pressure)) {
      return absl::InvalidArgumentError(absl::StrCat("pressure ", k, " is not finite"));
    }
    for (const Edge& edge : load.edges) {
      if (edge.nodes.size() != 2 && edge.nodes.size() != 3) {
        return absl::InvalidArgumentError(absl::StrCat("pressure ", k, " has an edge of ",
                                                       edge.nodes.size(), " nodes, not 2 or 3"));
      }
      for (int id : edge.nodes) {
        if (id < 0 || id >= nodes) {
          return absl::InvalidArgumentError(
              absl::StrCat("pressure ", k, " names node ", id, ", outside [0, ", nodes, ")"));
        }
      }
    }
  }
  return absl::OkStatus();
}

// Union–find over nodes: the mesh's connected parts.
int Find(std::vector<int>& parent, int a) {
  while (parent[a] != a) a = parent[a] = parent[parent[a]];
  return a;
}

}  // namespace

void AddFixed(std::span<const int> nodes, Boundary& boundary) {
  for (int dof : {0, 1}) AddRoller(nodes, dof, boundary);
}

void AddRoller(std::span<const int> nodes, int dof, Boundary& boundary) {
  for (int node : nodes) boundary.prescribed.push_back({node, dof, 0.0});
}

void AddPlaten(std::span<const int> nodes, int normal_dof, double increment, Platen platen,
               Boundary& boundary) {
  for (int node : nodes) boundary.prescribed.push_back({node, normal_dof, increment});
  if (platen == Platen::kRough) AddRoller(nodes, 1 - normal_dof, boundary);
}

void AddForcedPlaten(std::span<const int> nodes, int dof, double force_increment,
                     Boundary& boundary) {
  boundary.forced.push_back({std::vector<int>(nodes.begin(), nodes.end()), dof, force_increment});
}

absl::StatusOr<std::vector<PeriodicPair>> MatchPeriodicPairs(const Mesh& mesh,
                                                             std::span<const int> masters,
                                                             std::span<const int> slaves,
                                                             int along) {
  const int n = static_cast<int>(mesh.nodes.size());
  if (along != 0 && along != 1) {
    return absl::InvalidArgumentError(
        absl::StrCat("periodic pairs: axis ", along, " is not 0 or 1"));
  }
  double size = 0.0;
  for (const Eigen::Vector2d& x : mesh.nodes) size = std::max(size, x.cwiseAbs().maxCoeff());
  for (std::span<const int> side : {masters, slaves}) {
    for (int id : side) {
      if (id < 0 || id >= n) {
        return absl::InvalidArgumentError(
            absl::StrCat("periodic pairs: node ", id, " is outside [0, ", n, ")"));
      }
    }
  }
  std::vector<PeriodicPair> pairs;
  for (int slave : slaves) {
    const auto match = std::find_if(masters.begin(), masters.end(), [&](int master) {
      return std::abs(mesh.nodes[master][along] - mesh.nodes[slave][along]) <= 1e-9 * size;
    });
    if (match == masters.end()) {
      return absl::InvalidArgumentError(
          absl::StrFormat("periodic pairs: node %d at %s = %.9g m has no partner on the other side",
                          slave, AxisName(along), mesh.nodes[slave][along]));
    }
    pairs.push_back({*match, slave});
  }
  if (pairs.size() != masters.size()) {
    return absl::InvalidArgumentError(absl::StrCat("periodic pairs: ", masters.size(),
                                                   " nodes on one side, ", slaves.size(),
                                                   " on the other"));
  }
  return pairs;
}

absl::StatusOr<DofMap> DofMap::Create(int nodes, const Boundary& boundary) {
  const int dofs = 2 * nodes;
  if (!boundary.periodic_offset_increment.allFinite()) {
    return absl::InvalidArgumentError("the periodic offset increment is not finite");
  }
  if (absl::Status s = CheckPressures(nodes, boundary); !s.ok()) return s;
  std::vector<bool> prescribed(dofs, false);
  std::vector<double> increment(dofs, 0.0);
  for (const fem::Prescribed& p : boundary.prescribed) {
    if (p.node < 0 || p.node >= nodes || (p.dof != 0 && p.dof != 1)) {
      return absl::InvalidArgumentError(absl::StrCat("prescribed dof ", p.dof, " of node ", p.node,
                                                     " is out of range (", nodes, " nodes)"));
    }
    if (!std::isfinite(p.increment)) {
      return absl::InvalidArgumentError(
          absl::StrCat("node ", p.node, " dof ", AxisName(p.dof), ": the increment is not finite"));
    }
    const int d = 2 * p.node + p.dof;
    if (prescribed[d]) {
      return absl::InvalidArgumentError(
          absl::StrCat("node ", p.node, " dof ", AxisName(p.dof), " is prescribed twice"));
    }
    prescribed[d] = true;
    increment[d] = p.increment;
  }
  // master[d]: the dof a slave dof follows, −1 when none; periodic[d]:
  // whether that link adds the periodic offset (a platen's tie adds none).
  std::vector<int> master(dofs, -1);
  std::vector<bool> periodic(dofs, false);
  // The forced platen each dof is in, −1 when none.
  std::vector<int> platen(dofs, -1);
  for (std::size_t k = 0; k < boundary.forced.size(); ++k) {
    const ForcedPlaten& f = boundary.forced[k];
    if (f.nodes.empty() || (f.dof != 0 && f.dof != 1)) {
      return absl::InvalidArgumentError(absl::StrCat("forced platen ", k, " is invalid (",
                                                     f.nodes.size(), " nodes, dof ", f.dof, ")"));
    }
    if (!std::isfinite(f.force_increment)) {
      return absl::InvalidArgumentError(
          absl::StrCat("forced platen ", k, ": the force increment is not finite"));
    }
    for (int node : f.nodes) {
      if (node < 0 || node >= nodes) {
        return absl::InvalidArgumentError(
            absl::StrCat("forced platen ", k, " names node ", node, ", outside [0, ", nodes, ")"));
      }
      const int d = 2 * node + f.dof;
      if (prescribed[d]) {
        return absl::InvalidArgumentError(absl::StrCat("node ", node, " dof ", AxisName(f.dof),
                                                       " is both prescribed and in forced platen ",
                                                       k, " (a forced dof must be free)"));
      }
      if (platen[d] >= 0) {
        return absl::InvalidArgumentError(absl::StrCat("node ", node, " dof ", AxisName(f.dof),
                                                       " is in forced platen ", platen[d],
                                                       " and in forced platen ", k));
      }
      platen[d] = static_cast<int>(k);
      if (node != f.nodes[0]) master[d] = 2 * f.nodes[0] + f.dof;
    }
  }
  for (const PeriodicPair& pair : boundary.periodic) {
    if (pair.master < 0 || pair.master >= nodes || pair.slave < 0 || pair.slave >= nodes ||
        pair.master == pair.slave) {
      return absl::InvalidArgumentError(absl::StrCat("periodic pair (", pair.master, ", ",
                                                     pair.slave, ") is invalid (", nodes,
                                                     " nodes; a node cannot pair with itself)"));
    }
    for (int i : {0, 1}) {
      const int d = 2 * pair.slave + i;
      if (prescribed[d]) continue;
      if (const int k = platen[d]; k >= 0) {
        // Both in the platen: its tie already moves them as one.
        if (platen[2 * pair.master + i] != k) {
          return absl::InvalidArgumentError(
              absl::StrCat("node ", pair.slave, " of forced platen ", k,
                           " is the periodic slave of node ", pair.master, " outside it along ",
                           AxisName(i), " (list the platen on the masters' side)"));
        }
        if (boundary.periodic_offset_increment[i] != 0.0) {
          return absl::InvalidArgumentError(absl::StrCat(
              "the periodic offset increment along ", AxisName(i), " would stretch forced platen ",
              k, " (pair (", pair.master, ", ", pair.slave, "))"));
        }
        continue;
      }
      if (master[d] >= 0) {
        return absl::InvalidArgumentError(
            absl::StrCat("node ", pair.slave, " is the slave of two periodic pairs"));
      }
      master[d] = 2 * pair.master + i;
      periodic[d] = true;
    }
  }
  DofMap map;
  map.unknown_.assign(dofs, -1);
  map.value_.assign(dofs, 0.0);
  // Follow each dof to its root; every periodic link adds the offset.
  std::vector<int> root(dofs), links(dofs, 0);
  for (int d = 0; d < dofs; ++d) {
    int r = d;
    for (int steps = 1; master[r] >= 0; ++steps) {
      links[d] += periodic[r];
      r = master[r];
      if (steps > dofs) {
        return absl::InvalidArgumentError(
            absl::StrCat("the periodic pairs of node ", d / 2, " form a cycle"));
      }
    }
    root[d] = r;
  }
  for (int d = 0; d < dofs; ++d) {
    if (root[d] == d && !prescribed[d]) {
      map.unknown_[d] = map.unknowns_++;
      map.dof_of_.push_back(d);
    }
  }
  std::vector<Eigen::Triplet<double>> t;
  for (int d = 0; d < dofs; ++d) {
    const int r = root[d];
    map.value_[d] =
        (prescribed[r] ? increment[r] : 0.0) + links[d] * boundary.periodic_offset_increment[d % 2];
    map.unknown_[d] = map.unknown_[r];
    if (map.unknown_[d] >= 0) t.emplace_back(d, map.unknown_[d], 1.0);
  }
  map.t_.resize(dofs, map.unknowns_);
  map.t_.setFromTriplets(t.begin(), t.end());
  return map;
}

Eigen::VectorXd DofMap::Prescribed(double factor) const {
  return factor * Eigen::Map<const Eigen::VectorXd>(value_.data(), value_.size());
}

absl::Status CheckSupports(const Mesh& mesh, const DofMap& dofs) {
  const int nodes = static_cast<int>(mesh.nodes.size());
  std::vector<int> parent(nodes);
  std::iota(parent.begin(), parent.end(), 0);
  const auto join = [&parent](int a, int b) { parent[Find(parent, a)] = Find(parent, b); };
  for (const Element& e : mesh.elements) {
    for (int id : e.nodes) join(id, e.nodes[0]);
  }
  // A slave's dof follows its master's: that joins their parts.
  for (int d = 0; d < dofs.dofs(); ++d) {
    if (dofs.UnknownOf(d) >= 0) join(d / 2, dofs.DofOf(dofs.UnknownOf(d)) / 2);
  }
  std::map<int, std::vector<int>> parts;
  for (int a = 0; a < nodes; ++a) parts[Find(parent, a)].push_back(a);
  for (const auto& [part_root, members] : parts) {
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    for (int a : members) centre += mesh.nodes[a];
    centre /= static_cast<double>(members.size());
    double length = 0.0;
    for (int a : members) length = std::max(length, (mesh.nodes[a] - centre).norm());
    if (length == 0.0) length = 1.0;
    // A rigid motion's dof d: translations, and a rotation scaled by the
    // part's size so that the three columns compare.
    const auto rigid = [&](int d) {
      const Eigen::Vector2d r = (mesh.nodes[d / 2] - centre) / length;
      return Eigen::RowVector3d(d % 2 == 0, d % 2 == 1, d % 2 == 0 ? -r.y() : r.x());
    };
    // The homogeneous constraints on it: a prescribed dof does not move, a
    // slave moves with its master.
    std::vector<Eigen::RowVector3d> rows;
    for (int a : members) {
      for (int d : {2 * a, 2 * a + 1}) {
        if (dofs.UnknownOf(d) < 0) {
          rows.push_back(rigid(d));
        } else if (const int m = dofs.DofOf(dofs.UnknownOf(d)); m != d) {
          rows.push_back(rigid(d) - rigid(m));
        }
      }
    }
    Eigen::MatrixXd c = Eigen::MatrixXd::Zero(std::max<std::size_t>(rows.size(), 1), 3);
    for (std::size_t k = 0; k < rows.size(); ++k) c.row(k) = rows[k];
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(c, Eigen::ComputeFullV);
    const Eigen::VectorXd s = svd.singularValues();
    if (s.size() == 3 && s[2] > 1e-9 * s[0]) continue;
    const Eigen::Vector3d v = svd.matrixV().col(2);
    std::string motion;
    if (std::abs(v[2]) > 1e-9) {
      // The point that does not move: v_t + (ω/L) e_z × (x − centre) = 0.
      const double omega = v[2] / length;
      motion = absl::StrFormat("rotate about (%.6g, %.6g) m", centre.x() - v[1] / omega,
                               centre.y() + v[0] / omega);
    } else {
      // Round-off, and −0, printed as 0.
      const auto clean = [](double c) { return std::abs(c) < 1e-9 ? 0.0 : c; };
      motion = absl::StrFormat("translate along (%.3g, %.3g)", clean(v[0]), clean(v[1]));
    }
    return absl::FailedPreconditionError(
        absl::StrCat("the mesh has no supports against rigid-body motion: the part with node ",
                     members[0], " can ", motion, " (fix, roll or prescribe more dofs)"));
  }
  return absl::OkStatus();
}

}  // namespace rvehub::fem
