// A FemCase as the solver's problem (fem_client/run/problem.h), without
// RVEs: the core's Gauss points are the case's documented ids, each shipped
// case's faces get the conditions cases/FEM_FORMAT.md gives them (platens'
// increments, rollers, pins, pressures, periodic pairs, the shear platen),
// cycles reverse by the quarter, and what the run cannot do is refused.
#include "fem_client/run/problem.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/match.h"
#include "fem_client/case/case.h"

namespace rvehub::fem {
namespace {

FemCase Load(const std::string& name, std::vector<CaseOverride> overrides = {}) {
  absl::StatusOr<FemCase> c =
      LoadFemCase(std::string(RVEHUB_SOURCE_DIR "/cases/") + name + ".json", overrides);
  EXPECT_TRUE(c.ok()) << c.status();
  return c.ok() ? *c : FemCase{};
}

Problem Build(const FemCase& c) {
  absl::StatusOr<Problem> p = BuildProblem(c);
  EXPECT_TRUE(p.ok()) << p.status();
  return p.ok() ? *std::move(p) : Problem{};
}

// (node, dof) -> increment of the boundary's prescriptions, each once.
std::map<std::pair<int, int>, double> Prescriptions(const Problem& p) {
  std::map<std::pair<int, int>, double> out;
  for (const Prescribed& q : p.boundary.prescribed) {
    EXPECT_TRUE(out.emplace(std::pair{q.node, q.dof}, q.increment).second)
        << "node " << q.node << " dof " << q.dof << " prescribed twice";
  }
  return out;
}

const std::vector<int>& Nodes(const Problem& p, const char* face) {
  return p.mesh.node_sets.at(face);
}

// Gauss point id k = e·(4 or 9) + g with e = i + nx·j and g counting the
// element's points ξ fastest (cases/FEM_FORMAT.md): the core's k-th Gauss
// point is there, so RVE k needs no mapping.
TEST(ProblemTest, GaussPointsAreTheCasesNumbering) {
  for (const auto& [element, elements] :
       std::vector<std::pair<std::string, std::string>>{{"q4", "[4,3]"}, {"q8", "[2,3]"}}) {
    SCOPED_TRACE(element);
    FemCase c = Load("fem-biaxial-coarse-ci", {{"/mesh/element", "\"" + element + "\""},
                                               {"/mesh/elements", elements},
                                               {"/mesh/origin", "[0.5,-1]"}});
    const Problem p = Build(c);
    const std::vector<Eigen::Vector2d> x = GaussPointPositions(p.mesh, p.mesh.nodes);
    ASSERT_EQ(static_cast<std::int64_t>(x.size()), GaussPointCount(c.mesh));
    const int per_side = element == "q4" ? 2 : 3;
    const std::vector<double> xi =
        per_side == 2 ? std::vector<double>{-1 / std::sqrt(3.0), 1 / std::sqrt(3.0)}
                      : std::vector<double>{-std::sqrt(0.6), 0.0, std::sqrt(0.6)};
    const double dx = c.mesh.size.x() / c.mesh.nx, dy = c.mesh.size.y() / c.mesh.ny;
    for (int j = 0; j < c.mesh.ny; ++j) {
      for (int i = 0; i < c.mesh.nx; ++i) {
        for (int b = 0; b < per_side; ++b) {
          for (int a = 0; a < per_side; ++a) {
            const int e = i + c.mesh.nx * j, g = a + per_side * b;
            const int k = e * per_side * per_side + g;
            const Eigen::Vector2d expected =
                c.mesh.origin +
                Eigen::Vector2d((i + 0.5 * (1 + xi[a])) * dx, (j + 0.5 * (1 + xi[b])) * dy);
            EXPECT_LT((x[k] - expected).norm(), 1e-12) << "Gauss point " << k;
          }
        }
      }
    }
  }
}

// G&Z §3.3, Fig. 5: rollers left and bottom, 100 kPa on the right, a smooth
// platen on top pressed 0.1 % of the height per step.
TEST(ProblemTest, SingleElement) {
  const FemCase c = Load("fem-single-element");
  const Problem p = Build(c);
  EXPECT_EQ(p.driven, Face::kTop);
  EXPECT_EQ(p.lateral, Face::kRight);
  EXPECT_FALSE(p.shear);
  EXPECT_EQ(p.length_across, 1.0);
  EXPECT_EQ(p.factors, std::vector<double>(100, 1.0));
  EXPECT_TRUE(p.notes.empty());
  const auto q = Prescriptions(p);
  for (int node : Nodes(p, "top")) {
    EXPECT_DOUBLE_EQ(q.at({node, 1}), -1e-3);  // m: 0.1 % of 1 m, downwards
  }
  for (int node : Nodes(p, "left")) EXPECT_EQ(q.at({node, 0}), 0.0);
  for (int node : Nodes(p, "bottom")) EXPECT_EQ(q.at({node, 1}), 0.0);
  // Left x (2), bottom y (2), top y (2): the top-left corner's x from the
  // left roller; nothing else.
  EXPECT_EQ(q.size(), 6u);
  ASSERT_EQ(p.boundary.pressures.size(), 1u);
  EXPECT_EQ(p.boundary.pressures[0].pressure, 1e5);  // compression +, as the core takes it
  EXPECT_EQ(p.boundary.pressures[0].edges.size(), 1u);
  EXPECT_TRUE(p.boundary.periodic.empty());
  EXPECT_EQ(p.solver.tangent, TangentOperator::kContact);
  EXPECT_EQ(p.solver.displacement_tolerance, 0.01);
  EXPECT_EQ(p.solver.max_iterations, 30);
  EXPECT_EQ(p.solver.max_cutbacks, 6);
}

// G&Z §4, Fig. 9: smooth platens, the base a roller pinned at its middle
// node, 100 kPa on both sides; Q8 midside nodes included.
TEST(ProblemTest, BiaxialSpecimenWithPinnedBase) {
  for (const char* name : {"fem-biaxial-coarse", "fem-biaxial-coarse-q8"}) {
    SCOPED_TRACE(name);
    const FemCase c = Load(name);
    const Problem p = Build(c);
    const auto q = Prescriptions(p);
    const std::vector<int>& base = Nodes(p, "bottom");
    ASSERT_EQ(base.size() % 2, 1u);
    const int middle = base[base.size() / 2];
    EXPECT_NEAR(p.mesh.nodes[middle].x(), 0.025, 1e-15);
    EXPECT_EQ(q.at({middle, 0}), 0.0);
    for (int node : base) {
      EXPECT_EQ(q.at({node, 1}), 0.0);
      if (node != middle) {
        EXPECT_FALSE(q.contains({node, 0}));
      }
    }
    for (int node : Nodes(p, "top")) {
      EXPECT_DOUBLE_EQ(q.at({node, 1}), -1e-3 * 0.1);  // 0.1 % of 0.1 m
      EXPECT_FALSE(q.contains({node, 0}));             // smooth
    }
    EXPECT_EQ(q.size(), 2 * base.size() + 1);
    EXPECT_EQ(p.boundary.pressures.size(), 2u);
    EXPECT_EQ(p.factors.size(), 100u);
  }
}

// G&Z §5, Fig. 19: a fixed base, periodic sides, the top moved along +x by
// γ·H per step with its height held; a cycle's quarters go +, −, −, +.
TEST(ProblemTest, StrainControlledSimpleShear) {
  const FemCase c = Load("fem-simple-shear-strain-ci");
  const Problem p = Build(c);
  EXPECT_TRUE(p.shear);
  EXPECT_EQ(p.driven, Face::kTop);
  EXPECT_EQ(p.lateral, Face::kTop);
  EXPECT_EQ(p.length_across, 0.05);
  EXPECT_EQ(p.factors, (std::vector<double>{1, 1, -1, -1, -1, -1, 1, 1}));
  const auto q = Prescriptions(p);
  const double step = 4 * 0.01 / 8 * 0.05;  // m: 4A/steps of γ times H
  for (int node : Nodes(p, "top")) {
    EXPECT_DOUBLE_EQ(q.at({node, 0}), step);
    EXPECT_EQ(q.at({node, 1}), 0.0);
  }
  for (int node : Nodes(p, "bottom")) {
    EXPECT_EQ(q.at({node, 0}), 0.0);
    EXPECT_EQ(q.at({node, 1}), 0.0);
  }
  EXPECT_EQ(q.size(), 4 * Nodes(p, "top").size());
  // Every right node tied to the left node at its height.
  ASSERT_EQ(p.boundary.periodic.size(), Nodes(p, "right").size());
  for (const PeriodicPair& pair : p.boundary.periodic) {
    EXPECT_NEAR(p.mesh.nodes[pair.master].x(), 0.0, 1e-15);
    EXPECT_NEAR(p.mesh.nodes[pair.slave].x(), 0.1, 1e-15);
    EXPECT_EQ(p.mesh.nodes[pair.master].y(), p.mesh.nodes[pair.slave].y());
  }
  EXPECT_TRUE(p.boundary.pressures.empty());

  // Two cycles of twelve steps: quarters of three.
  const FemCase two = Load("fem-simple-shear-strain-ci",
                           {{"/loading/cycles", "2"}, {"/loading/steps_per_cycle", "12"}});
  const std::vector<double> cycle = {1, 1, 1, -1, -1, -1, -1, -1, -1, 1, 1, 1};
  std::vector<double> expected = cycle;
  expected.insert(expected.end(), cycle.begin(), cycle.end());
  EXPECT_EQ(Build(two).factors, expected);
}

// A platen on the left, pushed towards +x; the rough contact holds its y.
TEST(ProblemTest, RoughPlatenOnTheLeft) {
  const FemCase c =
      Load("fem-single-element",
           {{"/boundaries/0/kind", "\"platen\""},
            {"/boundaries/0/contact", "\"rough\""},
            {"/boundaries/2", R"({"name": "right", "face": "right", "kind": "roller"})"},
            {"/boundaries/3",
             R"({"name": "top", "face": "top", "kind": "pressure", "pressure": 1e5})"}});
  const Problem p = Build(c);
  EXPECT_EQ(p.driven, Face::kLeft);
  EXPECT_EQ(p.lateral, Face::kTop);
  const auto q = Prescriptions(p);
  for (int node : Nodes(p, "left")) {
    EXPECT_DOUBLE_EQ(q.at({node, 0}), 1e-3);  // into the specimen: +x
    EXPECT_EQ(q.at({node, 1}), 0.0);
  }
}

// A corner that a support would hold and the platen moves: the platen's
// motion stands, with a note naming the boundary and the node.
TEST(ProblemTest, ACornerTheDrivenFaceMovesIsNoted) {
  const FemCase c = Load("fem-single-element", {{"/boundaries/0/kind", "\"fixed\""}});
  const Problem p = Build(c);
  const auto q = Prescriptions(p);
  const int corner = Nodes(p, "left").back();  // the top-left node
  EXPECT_DOUBLE_EQ(q.at({corner, 1}), -1e-3);
  ASSERT_EQ(p.notes.size(), 1u);
  EXPECT_TRUE(absl::StrContains(p.notes[0], "boundary left would hold node")) << p.notes[0];
}

// Stress control (G&Z §5.2): the shear platen's nodes move together under a
// force of τ·W per step (τ = 4·30 kPa/8 on the 0.1 m wide specimen), the
// height held, nothing prescribed along x on the platen.
TEST(ProblemTest, StressControlledCyclesDriveTheShearPlatenByItsForce) {
  const Problem p = Build(Load("fem-simple-shear-stress-ci"));
  EXPECT_TRUE(p.shear);
  EXPECT_TRUE(p.forced);
  ASSERT_EQ(p.boundary.forced.size(), 1u);
  EXPECT_EQ(p.boundary.forced[0].nodes, Nodes(p, "top"));
  EXPECT_EQ(p.boundary.forced[0].dof, 0);
  EXPECT_DOUBLE_EQ(p.boundary.forced[0].force_increment, 4.0 * 30e3 / 8 * 0.1);
  const auto q = Prescriptions(p);
  for (int node : Nodes(p, "top")) {
    EXPECT_EQ(q.count({node, 0}), 0u) << node;
    EXPECT_EQ(q.at({node, 1}), 0.0) << node;
  }
  EXPECT_FALSE(Build(Load("fem-simple-shear-strain-ci")).forced);
}

// Every shipped case builds.
TEST(ProblemTest, EveryShippedCaseBuilds) {
  for (const char* name :
       {"fem-single-element", "fem-single-element-ci", "fem-biaxial-coarse", "fem-biaxial-medium",
        "fem-biaxial-fine", "fem-biaxial-coarse-q8", "fem-biaxial-coarse-ci",
        "fem-biaxial-coarse-q8-ci", "fem-simple-shear-strain", "fem-simple-shear-strain-ci",
        "fem-simple-shear-stress", "fem-simple-shear-stress-ci", "fem-biaxial-second-gradient",
        "fem-biaxial-second-gradient-ci"}) {
    SCOPED_TRACE(name);
    const FemCase c = Load(name);
    const Problem p = Build(c);
    EXPECT_EQ(CountGaussPoints(p.mesh), GaussPointCount(c.mesh));
    EXPECT_FALSE(p.factors.empty());
  }
}

}  // namespace
}  // namespace rvehub::fem
