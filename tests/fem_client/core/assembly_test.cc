#include "fem_client/core/assembly.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <vector>

#include "fem_client/core/elastic_material.h"
#include "tests/fem_client/core/fem_test_util.h"

namespace rvehub::fem {
namespace {

using testing::DistortedSquare;
using testing::InPlane;
using testing::InteriorNodes;
using testing::Prestress;

constexpr ElementType kTypes[] = {ElementType::kQ4, ElementType::kQ8};

// Consistent nodal forces of a pressure on a straight edge of length L:
// pL/2 at each end (2 nodes), pL/6 at the ends and 2pL/3 in the middle
// (3 nodes), inward.
TEST(AssemblyTest, PressuresGiveConsistentNodalForces) {
  const double p = 2e5, length = 0.5;
  const std::vector<Eigen::Vector2d> x = {{0, 0}, {0.3, 0.4}, {0.15, 0.2}};  // along (0.6, 0.8)
  const Eigen::Vector2d inward =
      -Eigen::Vector2d(0.8, -0.6);  // the tangent turned clockwise, reversed
  const Eigen::VectorXd two = PressureForces(6, std::vector<PressureLoad>{{{Edge{{0, 1}}}, p}}, x);
  EXPECT_LT((two.segment<2>(0) - p * length / 2 * inward).norm(), 1e-10);
  EXPECT_LT((two.segment<2>(2) - p * length / 2 * inward).norm(), 1e-10);
  EXPECT_EQ(two.segment<2>(4), Eigen::Vector2d::Zero());
  const Eigen::VectorXd three =
      PressureForces(6, std::vector<PressureLoad>{{{Edge{{0, 1, 2}}}, p}}, x);
  EXPECT_LT((three.segment<2>(0) - p * length / 6 * inward).norm(), 1e-10);
  EXPECT_LT((three.segment<2>(2) - p * length / 6 * inward).norm(), 1e-10);
  EXPECT_LT((three.segment<2>(4) - 2 * p * length / 3 * inward).norm(), 1e-10);
  // On a curved 3-node edge the total is still −p Q (x_end − x_start):
  // ∫ n ds over an open curve depends on its ends only.
  std::vector<Eigen::Vector2d> curved = x;
  curved[2] += Eigen::Vector2d(-0.1, 0.07);
  const Eigen::VectorXd bent =
      PressureForces(6, std::vector<PressureLoad>{{{Edge{{0, 1, 2}}}, p}}, curved);
  const Eigen::Vector2d total = bent.segment<2>(0) + bent.segment<2>(2) + bent.segment<2>(4);
  EXPECT_LT((total - p * length * inward).norm(), 1e-10);
}

// The patch test: on the distorted meshes a linear field gives every Gauss
// point the same ΔF, and a uniform stress leaves no force on an interior
// node (both exact for the isoparametric Q4 and Q8, curved sides and all,
// because the integrands are polynomials within the Gauss rules' degree:
// to round-off, 1e-10 of the boundary nodes' forces).
TEST(AssemblyTest, PatchTestOnDistortedMeshes) {
  Eigen::Matrix2d h;
  h << 2e-3, -1e-3, 4e-3, -3e-3;
  for (ElementType type : kTypes) {
    const Mesh mesh = DistortedSquare(type);
    ASSERT_TRUE(ValidateMesh(mesh).ok()) << ValidateMesh(mesh);
    Eigen::VectorXd du(2 * mesh.nodes.size());
    for (std::size_t a = 0; a < mesh.nodes.size(); ++a) du.segment<2>(2 * a) = h * mesh.nodes[a];
    const std::vector<PointGeometry> reference = *EvaluateGeometry(mesh, mesh.nodes);
    for (const Eigen::Matrix3d& f : DeformationIncrements(mesh, reference, du)) {
      EXPECT_LT((f - InPlane(Eigen::Matrix2d::Identity() + h)).norm(), 1e-15);
    }
    const std::vector<Eigen::Vector2d> x = Moved(mesh.nodes, du);
    const std::vector<PointGeometry> current = *EvaluateGeometry(mesh, x);
    const std::vector<PointResponse> uniform(current.size(), PointResponse{Prestress(), {}});
    const Eigen::VectorXd f = InternalForces(mesh, current, uniform);
    const double scale = f.cwiseAbs().maxCoeff();
    EXPECT_GT(scale, 1e4);
    const std::vector<int> interior = InteriorNodes(mesh);
    EXPECT_EQ(interior.size(), type == ElementType::kQ4 ? 1u : 5u);
    for (int a : interior) EXPECT_LT(f.segment<2>(2 * a).norm(), 1e-10 * scale) << a;
    // The boundary's forces are σ·n on the faces: they balance.
    EXPECT_LT(f.reshaped(2, f.size() / 2).rowwise().sum().norm(), 1e-10 * scale);
  }
}

// K = ∂R/∂Δu exactly: against central differences of R(Δu) = f_int − f_ext
// with the stiffening stand-in (prestressed, after a committed
// compression), a pressure on the top and a Δu that stretches, shears
// and turns each element differently. The differences' own error is
// O(h² ∂³R) ~ 1e-8 of K here; leaving out the initial-stress or the load
// terms errs by |σ|/|D| ~ 1e-3.
TEST(AssemblyTest, TheTangentIsTheDerivativeOfTheResidual) {
  for (ElementType type : kTypes) {
    const Mesh mesh = DistortedSquare(type);
    const int points = CountGaussPoints(mesh), dofs = 2 * static_cast<int>(mesh.nodes.size());
    const StiffeningParameters parameters{5e7, 3e7, 40.0};
    const StiffeningState committed{Prestress(), -0.005};
    const std::vector<PressureLoad> pressures = {{mesh.edge_sets.at("top"), 1.5e5}};
    const std::vector<PointGeometry> reference = *EvaluateGeometry(mesh, mesh.nodes);
    const auto residual = [&](const Eigen::VectorXd& du, std::vector<PointResponse>* out,
                              std::vector<PointGeometry>* geometry) {
      const std::vector<Eigen::Vector2d> x = Moved(mesh.nodes, du);
      const std::vector<PointGeometry> current = *EvaluateGeometry(mesh, x);
      std::vector<PointResponse> r(points);
      const std::vector<Eigen::Matrix3d> f = DeformationIncrements(mesh, reference, du);
      for (int p = 0; p < points; ++p) {
        Tangent d;
        r[p].stress = StiffeningStress(parameters, committed, f[p], &d);
        r[p].tangent = d;
      }
      if (out != nullptr) *out = r;
      if (geometry != nullptr) *geometry = current;
      return Eigen::VectorXd(InternalForces(mesh, current, r) - PressureForces(dofs, pressures, x));
    };
    Eigen::VectorXd du(dofs);
    for (int a = 0; a < dofs / 2; ++a) {
      const Eigen::Vector2d& x = mesh.nodes[a];
      du.segment<2>(2 * a) = Eigen::Vector2d(-4e-3 * x.y() + 1e-3 * x.x() * x.y(),
                                             -6e-3 * x.y() + 2e-3 * x.x() * x.x());
    }
    std::vector<PointResponse> responses;
    std::vector<PointGeometry> current;
    residual(du, &responses, &current);
    std::vector<Tangent> d;
    for (const PointResponse& r : responses) d.push_back(*r.tangent);
    const Eigen::MatrixXd k = Eigen::MatrixXd(
        TangentStiffness(mesh, reference, current, responses, d, pressures, Moved(mesh.nodes, du)));
    const double h = 1e-7;
    Eigen::MatrixXd fd(dofs, dofs);
    for (int m = 0; m < dofs; ++m) {
      Eigen::VectorXd step = Eigen::VectorXd::Zero(dofs);
      step[m] = h;
      fd.col(m) =
          (residual(du + step, nullptr, nullptr) - residual(du - step, nullptr, nullptr)) / (2 * h);
    }
    EXPECT_LT((k - fd).cwiseAbs().maxCoeff(), 1e-6 * k.cwiseAbs().maxCoeff())
        << ElementName(type) << ": largest error " << (k - fd).cwiseAbs().maxCoeff() << " of "
        << k.cwiseAbs().maxCoeff();
  }
}

}  // namespace
}  // namespace rvehub::fem
