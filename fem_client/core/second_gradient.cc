#include "fem_client/core/second_gradient.h"

#include <cmath>

#include "absl/strings/str_cat.h"

namespace rvehub::fem {
namespace {

// One Gauss point of a Q8R element on X: the Q8 gradients (for u), the
// corners' bilinear functions and gradients (for v) and the volume.
struct PointFields {
  ShapeGradient displacement_gradient;         // ∂N_a/∂X_j of the 8 nodes, 1/m
  Eigen::Vector4d micro;                       // N_c of the 4 corners, [-]
  Eigen::Matrix<double, 4, 2> micro_gradient;  // ∂N_c/∂X_k, 1/m
  double volume = 0.0;                         // m² per m
};

PointFields Fields(const ElementCoordinates& c, const GaussPoint& gp) {
  const ShapeGradient dn = ShapeDerivatives(ElementType::kQ8R, gp.xi);
  const Eigen::Matrix2d j = Jacobian(dn, c);
  const Eigen::Matrix2d j_inv = j.inverse();
  PointFields f;
  f.displacement_gradient = dn * j_inv;
  f.micro = ShapeFunctions(ElementType::kQ4, gp.xi);
  f.micro_gradient = ShapeDerivatives(ElementType::kQ4, gp.xi) * j_inv;
  f.volume = gp.weight * j.determinant();
  return f;
}

}  // namespace

SecondGradientModulus IsotropicSecondGradientModulus(double d) {
  // Rows Σ_111 ... Σ_222, columns ∂v_11/∂x_1 ... ∂v_22/∂x_2 (eq. 44).
  const double h = d / 2.0;
  SecondGradientModulus m;
  m << d, 0, 0, 0, 0, h, h, 0,   //
      0, h, h, 0, -h, 0, 0, h,   //
      0, h, h, 0, -h, 0, 0, h,   //
      0, 0, 0, d, 0, -h, -h, 0,  //
      0, -h, -h, 0, d, 0, 0, 0,  //
      h, 0, 0, -h, 0, h, h, 0,   //
      h, 0, 0, -h, 0, h, h, 0,   //
      0, h, h, 0, 0, 0, 0, d;
  return m;
}

absl::StatusOr<SecondGradient> SecondGradient::Create(const Mesh& mesh, double modulus) {
  if (!(modulus > 0.0 && std::isfinite(modulus))) {
    return absl::InvalidArgumentError(
        absl::StrCat("the second-gradient modulus D must be positive and finite, got ", modulus));
  }
  std::vector<int> corner(mesh.nodes.size(), -1);
  for (std::size_t e = 0; e < mesh.elements.size(); ++e) {
    const Element& element = mesh.elements[e];
    if (element.type != ElementType::kQ8R) {
      return absl::InvalidArgumentError(absl::StrCat(
          "the second gradient needs Q8R elements (Q8 displacements, 2 x 2 Gauss points, the "
          "micro-kinematic field on the corners); element ",
          e, " is ", ElementName(element.type)));
    }
    for (int a = 0; a < 4; ++a) corner[element.nodes[a]] = 0;  // a corner
  }
  // Numbered in node order, so that the unknowns do not depend on which
  // element met a node first.
  int corners = 0;
  for (int& c : corner) {
    if (c >= 0) c = corners++;
  }
  return SecondGradient(std::move(corner), corners, static_cast<int>(mesh.elements.size()),
                        modulus);
}

SecondGradientState SecondGradient::Initial() const {
  SecondGradientState s;
  s.double_stress.assign(4 * static_cast<std::size_t>(elements_), DoubleStress::Zero());
  s.multiplier = Eigen::VectorXd::Zero(4 * elements_);
  s.micro = Eigen::VectorXd::Zero(4 * corner_nodes_);
  return s;
}

SecondGradient::Terms SecondGradient::Evaluate(const Mesh& mesh, std::span<const Eigen::Vector2d> x,
                                               const SecondGradientState& committed,
                                               const Eigen::VectorXd& du,
                                               const Eigen::VectorXd& ds) const {
  Terms t;
  t.internal = Eigen::VectorXd::Zero(2 * static_cast<Eigen::Index>(mesh.nodes.size()));
  t.residual = Eigen::VectorXd::Zero(unknowns());
  t.double_stress.reserve(committed.double_stress.size());
  const std::span<const GaussPoint> points = GaussPoints(ElementType::kQ8R);
  for (int e = 0; e < elements_; ++e) {
    const std::vector<int>& nodes = mesh.elements[e].nodes;
    const ElementCoordinates c = ElementPositions(mesh, e, x);
    Eigen::Vector4d lambda;  // λ_ij at the step's end, Pa
    for (int k = 0; k < 4; ++k) {
      lambda[k] = committed.multiplier[4 * e + k] + ds[MultiplierUnknown(e, k)];
    }
    for (std::size_t p = 0; p < points.size(); ++p) {
      const PointFields f = Fields(c, points[p]);
      Eigen::Matrix2d grad_u = Eigen::Matrix2d::Zero();  // ∂Δu_i/∂X_j
      for (int a = 0; a < 8; ++a) {
        grad_u += du.segment<2>(2 * nodes[a]) * f.displacement_gradient.row(a);
      }
      Eigen::Vector4d v = Eigen::Vector4d::Zero();  // Δv_ij
      Eigen::Matrix<double, 8, 1> grad_v;           // ∂Δv_ij/∂X_k
      grad_v.setZero();
      for (int a = 0; a < 4; ++a) {
        const Eigen::Vector4d va = ds.segment<4>(MicroUnknown(nodes[a], 0));
        v += f.micro[a] * va;
        for (int ij = 0; ij < 4; ++ij) {
          for (int k = 0; k < 2; ++k) grad_v[2 * ij + k] += va[ij] * f.micro_gradient(a, k);
        }
      }
      const DoubleStress sigma2 = committed.double_stress[4 * e + p] + modulus_ * grad_v;
      t.double_stress.push_back(sigma2);
      for (int a = 0; a < 8; ++a) {
        for (int i = 0; i < 2; ++i) {
          for (int j = 0; j < 2; ++j) {
            t.internal[2 * nodes[a] + i] -=
                f.volume * lambda[2 * i + j] * f.displacement_gradient(a, j);
          }
        }
      }
      for (int a = 0; a < 4; ++a) {
        for (int ij = 0; ij < 4; ++ij) {
          double r = lambda[ij] * f.micro[a];
          for (int k = 0; k < 2; ++k) r += sigma2[2 * ij + k] * f.micro_gradient(a, k);
          t.residual[MicroUnknown(nodes[a], ij)] += f.volume * r;
        }
      }
      for (int i = 0; i < 2; ++i) {
        for (int j = 0; j < 2; ++j) {
          t.residual[MultiplierUnknown(e, 2 * i + j)] += f.volume * (grad_u(i, j) - v[2 * i + j]);
        }
      }
    }
  }
  return t;
}

Eigen::SparseMatrix<double> SecondGradient::Stiffness(const Mesh& mesh,
                                                      std::span<const Eigen::Vector2d> x) const {
  const int dofs = 2 * static_cast<int>(mesh.nodes.size());
  const int size = dofs + unknowns();
  std::vector<Eigen::Triplet<double>> t;
  const std::span<const GaussPoint> points = GaussPoints(ElementType::kQ8R);
  for (int e = 0; e < elements_; ++e) {
    const std::vector<int>& nodes = mesh.elements[e].nodes;
    const ElementCoordinates c = ElementPositions(mesh, e, x);
    for (const GaussPoint& gp : points) {
      const PointFields f = Fields(c, gp);
      const double dv = f.volume;
      for (int i = 0; i < 2; ++i) {
        for (int j = 0; j < 2; ++j) {
          const int lam = dofs + MultiplierUnknown(e, 2 * i + j);
          for (int a = 0; a < 8; ++a) {
            const int u = 2 * nodes[a] + i;
            t.emplace_back(u, lam, -dv * f.displacement_gradient(a, j));
            t.emplace_back(lam, u, dv * f.displacement_gradient(a, j));
          }
          for (int a = 0; a < 4; ++a) {
            const int v = dofs + MicroUnknown(nodes[a], 2 * i + j);
            t.emplace_back(v, lam, dv * f.micro[a]);
            t.emplace_back(lam, v, -dv * f.micro[a]);
          }
        }
      }
      // ∫ ∂δv_ij/∂X_k M ∂Δv_mn/∂X_l dV.
      for (int a = 0; a < 4; ++a) {
        for (int b = 0; b < 4; ++b) {
          for (int ij = 0; ij < 4; ++ij) {
            for (int mn = 0; mn < 4; ++mn) {
              double kab = 0.0;
              for (int k = 0; k < 2; ++k) {
                for (int l = 0; l < 2; ++l) {
                  kab += f.micro_gradient(a, k) * modulus_(2 * ij + k, 2 * mn + l) *
                         f.micro_gradient(b, l);
                }
              }
              if (kab != 0.0) {
                t.emplace_back(dofs + MicroUnknown(nodes[a], ij), dofs + MicroUnknown(nodes[b], mn),
                               dv * kab);
              }
            }
          }
        }
      }
    }
  }
  Eigen::SparseMatrix<double> k(size, size);
  k.setFromTriplets(t.begin(), t.end());
  return k;
}

SecondGradientState SecondGradient::Advance(const SecondGradientState& committed,
                                            const Eigen::VectorXd& ds,
                                            std::vector<DoubleStress> double_stress) const {
  SecondGradientState s;
  s.double_stress = std::move(double_stress);
  s.multiplier = committed.multiplier + ds.tail(4 * elements_);
  s.micro = committed.micro + ds.head(4 * corner_nodes_);
  return s;
}

}  // namespace rvehub::fem
