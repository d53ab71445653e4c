// Boundary conditions: prescribed displacement increments per load step
// (fixed, rollers, platens), periodic node pairs, rigid platens under force
// control, constant pressures on boundary edges; and their elimination from
// the unknowns (DofMap).
// Degrees of freedom: 2 per node, dof 2a + i for node a along axis i.
#ifndef RVEHUB_FEM_CLIENT_CORE_BOUNDARY_H_
#define RVEHUB_FEM_CLIENT_CORE_BOUNDARY_H_

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "fem_client/core/mesh.h"

namespace rvehub::fem {

// Δu of one dof over each load step (0: held fixed), m.
struct Prescribed {
  int node = 0;
  int dof = 0;  // 0: x, 1: y
  double increment = 0.0;
};

// u_slave − u_master = the periodic offset (e.g. a right-side node and the
// left-side node at the same height). A prescribed dof of the slave keeps
// its prescription and drops the pair's constraint for that dof (the corner
// of a box held by the platens at both sides).
struct PeriodicPair {
  int master = 0;
  int slave = 0;
};

// A constant pressure on boundary edges, normal to them in the current
// configuration (a follower load).
struct PressureLoad {
  std::vector<Edge> edges;
  double pressure = 0.0;  // Pa, compression positive
};

// A rigid platen under force control (a stress-controlled shear: Guo & Zhao
// 2014 §5.2): the nodes' dof `dof` moves as one, each node's tied to the
// first node's (the master) by the master–slave elimination, and the total
// external force on that dof, a dead load starting from 0, grows by
// `force_increment` over each load step. The nodes' other dof may be
// prescribed (a platen whose height is held) or free. With periodic pairs:
// - a pair of two nodes of the platen (the top corners of a periodic
//   specimen) is implied along `dof` by the tie and dropped there; it is
//   kept along the other dof. The periodic offset increment along `dof`
//   must then be 0 (it would stretch the rigid platen);
// - a node of the platen may be a pair's master: its slave follows the
//   platen (and is loaded with it: the force acts on all that moves as
//   one);
// - a node of the platen must not be the slave of a node outside it (the
//   platen would follow that node: list the platen on the masters' side).
// No node's `dof` may be prescribed (the force would go to a support), and
// a dof is in one forced platen at most.
struct ForcedPlaten {
  std::vector<int> nodes;        // the first is the master
  int dof = 0;                   // 0: x, 1: y
  double force_increment = 0.0;  // along dof, per load step, N/m (per metre of thickness)
};

struct Boundary {
  std::vector<Prescribed> prescribed;  // at most one per (node, dof)
  std::vector<PeriodicPair> periodic;
  // Δ(u_slave − u_master) over each load step, m.
  Eigen::Vector2d periodic_offset_increment = Eigen::Vector2d::Zero();
  std::vector<ForcedPlaten> forced;
  std::vector<PressureLoad> pressures;
};

// Appends: both dofs held.
void AddFixed(std::span<const int> nodes, Boundary& boundary);
// Appends: one dof held (a roller along the other axis).
void AddRoller(std::span<const int> nodes, int dof, Boundary& boundary);
// A platen moving by `increment` (m per load step) along `normal_dof`:
// smooth, only the normal dof prescribed; rough, the tangential one held too.
enum class Platen { kSmooth, kRough };
void AddPlaten(std::span<const int> nodes, int normal_dof, double increment, Platen platen,
               Boundary& boundary);
// Appends a rigid platen of `nodes` (the first its master) under force
// control along `dof`: `force_increment` N/m per load step. Hold or move its
// other dof with AddRoller or Prescribed entries.
void AddForcedPlaten(std::span<const int> nodes, int dof, double force_increment,
                     Boundary& boundary);

// Pairs each slave with the master at the same position along `along` (0: x,
// 1: y) to 1e-9 of the mesh's size (left and right sides: along = 1).
// InvalidArgument naming a node with no partner.
absl::StatusOr<std::vector<PeriodicPair>> MatchPeriodicPairs(const Mesh& mesh,
                                                             std::span<const int> masters,
                                                             std::span<const int> slaves,
                                                             int along);

// The master–slave elimination of the constraints: every dof u = T q + g,
// with q the independent (free) unknowns, T a 0/1 matrix (a slave takes its
// master's unknown: periodic pairs, and the ties of forced platens) and g
// the prescribed part (prescribed increments, the periodic offsets), so
// that the reduced system is Tᵀ K T δq = −Tᵀ R. A forced platen's master
// dof stays an unknown, its force a load on it (assembled by the solver).
class DofMap {
 public:
  // InvalidArgument for a node or dof out of range, a (node, dof)
  // prescribed twice, a non-finite increment or offset, a pair of a node
  // with itself, a slave with two masters, a cycle of pairs, a pressure
  // that is not finite or on an edge of other than 2 or 3 nodes in range,
  // or a forced platen that is empty, has a non-finite force increment,
  // shares a dof with another one, holds a prescribed dof (naming the
  // node), holds the slave of a pair whose master is outside it, or would
  // be stretched by the periodic offset (see ForcedPlaten).
  static absl::StatusOr<DofMap> Create(int nodes, const Boundary& boundary);

  int dofs() const { return static_cast<int>(unknown_.size()); }
  int unknowns() const { return unknowns_; }
  const Eigen::SparseMatrix<double>& expand() const { return t_; }  // T, dofs × unknowns
  // g for a step scaled by `factor` (a cut-back part of a step, a reversed
  // cycle), m.
  Eigen::VectorXd Prescribed(double factor) const;
  bool IsPrescribed(int dof) const { return unknown_[dof] < 0; }
  // The dof an unknown stands for (a master's or a free node's own), and a
  // dof's unknown (−1 when prescribed, also through its master).
  int DofOf(int unknown) const { return dof_of_[unknown]; }
  int UnknownOf(int dof) const { return unknown_[dof]; }

 private:
  std::vector<int> unknown_;   // each dof's unknown, −1 when prescribed
  std::vector<double> value_;  // each dof's g for factor 1, m
  std::vector<int> dof_of_;
  int unknowns_ = 0;
  Eigen::SparseMatrix<double> t_;
};

// FailedPrecondition "the mesh has no supports against rigid-body motion
// ..." (naming a free motion: a translation or a rotation about a point)
// when some connected part of the mesh (periodic pairs and forced platens
// connect) can move rigidly without violating the constraints; its
// stiffness would be singular. A forced platen's dof is free: no support.
absl::Status CheckSupports(const Mesh& mesh, const DofMap& dofs);

}  // namespace rvehub::fem

#endif  // RVEHUB_FEM_CLIENT_CORE_BOUNDARY_H_
