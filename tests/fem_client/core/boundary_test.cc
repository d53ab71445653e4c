#include "fem_client/core/boundary.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/match.h"
#include "fem_client/core/mesh.h"

namespace rvehub::fem {
namespace {

Mesh Square(int n = 2, ElementType type = ElementType::kQ4) {
  RectangleSpec spec;
  spec.nx = spec.ny = n;
  spec.type = type;
  return *StructuredRectangle(spec);
}

void ExpectError(const absl::Status& s, absl::StatusCode code, const std::string& says) {
  EXPECT_EQ(s.code(), code) << s;
  EXPECT_TRUE(absl::StrContains(s.message(), says)) << s << "\nshould say: " << says;
}

TEST(BoundaryTest, PlatensAndRollersPrescribeTheirDofs) {
  Boundary b;
  const std::vector<int> nodes = {4, 5};
  AddPlaten(nodes, 1, -1e-3, Platen::kSmooth, b);
  ASSERT_EQ(b.prescribed.size(), 2u);
  EXPECT_EQ(b.prescribed[1].dof, 1);
  EXPECT_EQ(b.prescribed[1].increment, -1e-3);
  AddPlaten(std::vector<int>{0}, 0, 2e-3, Platen::kRough, b);
  ASSERT_EQ(b.prescribed.size(), 4u);
  EXPECT_EQ(b.prescribed[3].dof, 1);  // the tangential dof held
  EXPECT_EQ(b.prescribed[3].increment, 0.0);
  AddFixed(std::vector<int>{7}, b);
  EXPECT_EQ(b.prescribed.size(), 6u);
}

TEST(BoundaryTest, TheDofMapEliminatesPrescribedDofsAndSlaves) {
  // 3 nodes: node 0 fixed in x, moved by 2 mm in y; node 2 the slave of 1.
  Boundary b;
  b.prescribed = {{0, 0, 0.0}, {0, 1, 2e-3}};
  b.periodic = {{1, 2}};
  b.periodic_offset_increment = Eigen::Vector2d(1e-3, -5e-4);
  const absl::StatusOr<DofMap> map = DofMap::Create(3, b);
  ASSERT_TRUE(map.ok()) << map.status();
  EXPECT_EQ(map->dofs(), 6);
  EXPECT_EQ(map->unknowns(), 2);  // node 1's x and y
  EXPECT_TRUE(map->IsPrescribed(1));
  EXPECT_FALSE(map->IsPrescribed(4));
  EXPECT_EQ(map->UnknownOf(4), map->UnknownOf(2));
  EXPECT_EQ(map->DofOf(map->UnknownOf(5)), 3);
  // u = T q + g, for half a step.
  const Eigen::VectorXd g = map->Prescribed(0.5);
  EXPECT_EQ(g, (Eigen::VectorXd(6) << 0, 1e-3, 0, 0, 5e-4, -2.5e-4).finished());
  const Eigen::VectorXd u = map->expand() * Eigen::Vector2d(7, 8) + g;
  EXPECT_NEAR(u[4] - u[2], 5e-4, 1e-15);
  EXPECT_NEAR(u[5] - u[3], -2.5e-4, 1e-15);
}

// A corner held by both platens stays prescribed; a chain of pairs adds the
// offset at each link.
TEST(BoundaryTest, PrescribedSlavesKeepTheirPrescriptionAndChainsAddOffsets) {
  Boundary b;
  b.prescribed = {{1, 0, 3e-3}};
  b.periodic = {{0, 1}, {1, 2}};
  b.periodic_offset_increment = Eigen::Vector2d(1e-3, 2e-3);
  const absl::StatusOr<DofMap> map = DofMap::Create(3, b);
  ASSERT_TRUE(map.ok()) << map.status();
  const Eigen::VectorXd g = map->Prescribed(1.0);
  EXPECT_TRUE(map->IsPrescribed(2));  // node 1's x
  EXPECT_EQ(g[2], 3e-3);
  EXPECT_EQ(g[4], 3e-3 + 1e-3);  // node 2's x follows node 1's prescription
  EXPECT_EQ(g[5], 2 * 2e-3);     // y: node 2 → 1 → 0, two links
  EXPECT_EQ(map->UnknownOf(5), map->UnknownOf(1));
}

TEST(BoundaryTest, InconsistentConstraintsAreNamed) {
  const auto create = [](Boundary b) { return DofMap::Create(4, b).status(); };
  Boundary b;
  b.prescribed = {{2, 1, 0.0}, {2, 1, 1.0}};
  ExpectError(create(b), absl::StatusCode::kInvalidArgument, "node 2 dof y is prescribed twice");
  b.prescribed = {{4, 0, 0.0}};
  ExpectError(create(b), absl::StatusCode::kInvalidArgument, "out of range");
  b.prescribed = {{1, 0, std::nan("")}};
  ExpectError(create(b), absl::StatusCode::kInvalidArgument, "not finite");
  b.prescribed.clear();
  b.periodic = {{0, 1}, {2, 1}};
  ExpectError(create(b), absl::StatusCode::kInvalidArgument, "slave of two periodic pairs");
  b.periodic = {{0, 1}, {1, 0}};
  ExpectError(create(b), absl::StatusCode::kInvalidArgument, "form a cycle");
  b.periodic = {{3, 3}};
  ExpectError(create(b), absl::StatusCode::kInvalidArgument, "cannot pair with itself");
  b.periodic.clear();
  b.pressures = {{{Edge{{0, 9}}}, 1e5}};
  ExpectError(create(b), absl::StatusCode::kInvalidArgument, "pressure 0 names node 9");
}

// G&Z §5.2's simple shear on 3 × 3 nodes: bottom fixed, sides periodic,
// the top a rough platen whose height is held and whose x is under force
// control. Every top x shares the platen master's unknown; the top corners'
// pair is implied along x by the tie (whichever corner is the master) and
// kept along y (held there); node 5 follows node 3. A forced dof is no
// support, yet this set-up holds the mesh.
TEST(BoundaryTest, AForcedPlatenTiesItsNodesToItsMaster) {
  const Mesh mesh = Square();
  for (bool reversed : {false, true}) {
    std::vector<int> top = mesh.node_sets.at("top");  // 6, 7, 8
    if (reversed) std::reverse(top.begin(), top.end());
    Boundary b;
    AddFixed(mesh.node_sets.at("bottom"), b);
    AddRoller(top, 1, b);
    AddForcedPlaten(top, 0, 3e3, b);
    ASSERT_EQ(b.forced.size(), 1u);
    EXPECT_EQ(b.forced[0].nodes, top);
    EXPECT_EQ(b.forced[0].dof, 0);
    EXPECT_EQ(b.forced[0].force_increment, 3e3);
    b.periodic =
        *MatchPeriodicPairs(mesh, mesh.node_sets.at("left"), mesh.node_sets.at("right"), 1);
    const absl::StatusOr<DofMap> map = DofMap::Create(9, b);
    ASSERT_TRUE(map.ok()) << map.status();
    EXPECT_EQ(map->unknowns(), 5);  // nodes 3 and 4 (x, y), the platen's x
    const int master = 2 * top[0];
    EXPECT_EQ(map->DofOf(map->UnknownOf(master)), master);
    for (int a : top) {
      EXPECT_EQ(map->UnknownOf(2 * a), map->UnknownOf(master)) << a;
      EXPECT_TRUE(map->IsPrescribed(2 * a + 1)) << a;
    }
    EXPECT_EQ(map->UnknownOf(10), map->UnknownOf(6));
    EXPECT_EQ(map->Prescribed(1.0), Eigen::VectorXd::Zero(18));
    EXPECT_TRUE(CheckSupports(mesh, *map).ok());
  }
}

// A periodic slave outside a platen follows it, with the offset; the
// platen's other dof keeps its pairs.
TEST(BoundaryTest, APeriodicSlaveOfAPlatenNodeFollowsThePlaten) {
  Boundary b;
  AddForcedPlaten(std::vector<int>{0, 1}, 0, -2e3, b);
  b.periodic = {{1, 2}};
  b.periodic_offset_increment = Eigen::Vector2d(1e-3, 2e-3);
  const absl::StatusOr<DofMap> map = DofMap::Create(3, b);
  ASSERT_TRUE(map.ok()) << map.status();
  EXPECT_EQ(map->unknowns(), 3);  // the platen's x, node 0's and node 1's y
  EXPECT_EQ(map->UnknownOf(2), map->UnknownOf(0));
  EXPECT_EQ(map->UnknownOf(4), map->UnknownOf(0));
  EXPECT_EQ(map->UnknownOf(5), map->UnknownOf(3));
  const Eigen::VectorXd g = map->Prescribed(1.0);
  EXPECT_EQ(g, (Eigen::VectorXd(6) << 0, 0, 0, 0, 1e-3, 2e-3).finished());  // the tie adds none
}

TEST(BoundaryTest, ForcedPlatensThatConflictAreNamed) {
  const Mesh mesh = Square();
  const std::vector<int>& top = mesh.node_sets.at("top");
  const std::vector<PeriodicPair> sides =
      *MatchPeriodicPairs(mesh, mesh.node_sets.at("left"), mesh.node_sets.at("right"), 1);
  const auto create = [](const Boundary& b) { return DofMap::Create(9, b).status(); };
  Boundary b;
  AddForcedPlaten(top, 0, 1e3, b);
  AddRoller(std::vector<int>{7}, 0, b);
  ExpectError(create(b), absl::StatusCode::kInvalidArgument,
              "node 7 dof x is both prescribed and in forced platen 0");
  b = {};
  AddForcedPlaten(top, 0, 1e3, b);
  AddForcedPlaten(std::vector<int>{8, 5}, 0, 1e3, b);
  ExpectError(create(b), absl::StatusCode::kInvalidArgument,
              "node 8 dof x is in forced platen 0 and in forced platen 1");
  b.forced = {{{}, 0, 1e3}};
  ExpectError(create(b), absl::StatusCode::kInvalidArgument, "forced platen 0 is invalid (0 nodes");
  b.forced = {{{1}, 2, 1e3}};
  ExpectError(create(b), absl::StatusCode::kInvalidArgument, "forced platen 0 is invalid");
  b.forced = {{{9}, 0, 1e3}};
  ExpectError(create(b), absl::StatusCode::kInvalidArgument, "forced platen 0 names node 9");
  b.forced = {{{1}, 0, std::nan("")}};
  ExpectError(create(b), absl::StatusCode::kInvalidArgument, "force increment is not finite");
  // The right side under force while periodic slaves of the left one.
  b = {};
  AddForcedPlaten(mesh.node_sets.at("right"), 0, 1e3, b);
  b.periodic = sides;
  ExpectError(create(b), absl::StatusCode::kInvalidArgument,
              "node 2 of forced platen 0 is the periodic slave of node 0 outside it along x");
  // A periodic offset along the platen's dof between two of its nodes.
  b = {};
  AddForcedPlaten(top, 0, 1e3, b);
  b.periodic = sides;
  b.periodic_offset_increment = Eigen::Vector2d(1e-3, 0.0);
  ExpectError(create(b), absl::StatusCode::kInvalidArgument,
              "the periodic offset increment along x would stretch forced platen 0");
  b.periodic_offset_increment = Eigen::Vector2d(0.0, 1e-3);  // along y: the pair holds there
  EXPECT_TRUE(create(b).ok()) << create(b);
}

// The force does not hold the platen: with the bottom on rollers and the
// top's height held, the mesh slides along x.
TEST(BoundaryTest, AForcedDofIsNoSupport) {
  const Mesh mesh = Square();
  Boundary b;
  AddRoller(mesh.node_sets.at("bottom"), 1, b);
  AddRoller(mesh.node_sets.at("top"), 1, b);
  AddForcedPlaten(mesh.node_sets.at("top"), 0, 1e3, b);
  const absl::StatusOr<DofMap> map = DofMap::Create(9, b);
  ASSERT_TRUE(map.ok()) << map.status();
  ExpectError(CheckSupports(mesh, *map), absl::StatusCode::kFailedPrecondition,
              "can translate along (");
}

TEST(BoundaryTest, PeriodicPairsMatchNodesAtTheSameHeight) {
  const Mesh mesh = Square(2, ElementType::kQ8);
  const absl::StatusOr<std::vector<PeriodicPair>> pairs =
      MatchPeriodicPairs(mesh, mesh.node_sets.at("left"), mesh.node_sets.at("right"), 1);
  ASSERT_TRUE(pairs.ok()) << pairs.status();
  ASSERT_EQ(pairs->size(), 5u);
  for (const PeriodicPair& p : *pairs) {
    EXPECT_EQ(mesh.nodes[p.master].y(), mesh.nodes[p.slave].y());
    EXPECT_EQ(mesh.nodes[p.master].x(), 0.0);
    EXPECT_EQ(mesh.nodes[p.slave].x(), 1.0);
  }
  const std::vector<int> interior = {6};  // at y = 0.25, no partner on the bottom
  ExpectError(MatchPeriodicPairs(mesh, mesh.node_sets.at("bottom"), interior, 1).status(),
              absl::StatusCode::kInvalidArgument, "node 6 at y = 0.25 m has no partner");
}

TEST(BoundaryTest, SupportsThatHoldTheMeshPass) {
  const Mesh mesh = Square();
  Boundary b;
  AddRoller(mesh.node_sets.at("bottom"), 1, b);
  AddRoller(mesh.node_sets.at("left"), 0, b);
  EXPECT_TRUE(CheckSupports(mesh, *DofMap::Create(9, b)).ok());
  // Simple shear with periodic sides: bottom fixed.
  Boundary shear;
  AddFixed(mesh.node_sets.at("bottom"), shear);
  shear.periodic =
      *MatchPeriodicPairs(mesh, mesh.node_sets.at("left"), mesh.node_sets.at("right"), 1);
  EXPECT_TRUE(CheckSupports(mesh, *DofMap::Create(9, shear)).ok());
}

TEST(BoundaryTest, AMeshFreeToMoveRigidlyHasNoSupports) {
  const Mesh mesh = Square();
  const auto check = [&mesh](const Boundary& b) {
    const absl::StatusOr<DofMap> map = DofMap::Create(9, b);
    EXPECT_TRUE(map.ok()) << map.status();
    return CheckSupports(mesh, *map);
  };
  Boundary none;
  none.pressures = {{mesh.edge_sets.at("top"), 1e5}};
  ExpectError(check(none), absl::StatusCode::kFailedPrecondition,
              "the mesh has no supports against rigid-body motion");
  // One pinned corner: it can still turn about that corner.
  Boundary pinned;
  AddFixed(std::vector<int>{8}, pinned);
  ExpectError(check(pinned), absl::StatusCode::kFailedPrecondition, "rotate about (1, 1) m");
  // Rollers all along x: it slides along x.
  Boundary rollers;
  AddRoller(mesh.node_sets.at("bottom"), 1, rollers);
  ExpectError(check(rollers), absl::StatusCode::kFailedPrecondition, "translate along (");
  // Periodic sides alone do not stop a vertical translation.
  Boundary periodic;
  periodic.periodic =
      *MatchPeriodicPairs(mesh, mesh.node_sets.at("left"), mesh.node_sets.at("right"), 1);
  AddRoller(std::vector<int>{4}, 0, periodic);
  ExpectError(check(periodic), absl::StatusCode::kFailedPrecondition, "translate along (0, ");
}

// Each connected part needs its own supports.
TEST(BoundaryTest, EveryPartOfTheMeshNeedsSupports) {
  Mesh mesh = Square(1);
  const int n = static_cast<int>(mesh.nodes.size());
  for (int a = 0; a < n; ++a) mesh.nodes.push_back(mesh.nodes[a] + Eigen::Vector2d(3, 0));
  Element second = mesh.elements[0];
  for (int& id : second.nodes) id += n;
  mesh.elements.push_back(second);
  Boundary b;
  AddFixed(std::vector<int>{0, 1}, b);
  ExpectError(CheckSupports(mesh, *DofMap::Create(2 * n, b)), absl::StatusCode::kFailedPrecondition,
              "the part with node 4");
}

}  // namespace
}  // namespace rvehub::fem
