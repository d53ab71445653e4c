#include "fem_client/core/assembly.h"

namespace rvehub::fem {
namespace {

// Q turns an edge's tangent clockwise into its outward normal: the body lies
// on the tangent's left (Edge, mesh.h). n ds = Q (dx/ds) ds.
Eigen::Matrix2d Clockwise() {
  Eigen::Matrix2d q;
  q << 0.0, 1.0, -1.0, 0.0;
  return q;
}

// W_ab = ∫ N_a dN_b/ds ds over an edge of `nodes` nodes.
Eigen::Matrix3d EdgeMoments(int nodes) {
  Eigen::Matrix3d w = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector2d& g : EdgeGaussPoints()) {
    w += g[1] * EdgeShapeFunctions(nodes, g[0]) * EdgeShapeDerivatives(nodes, g[0]).transpose();
  }
  return w;
}

}  // namespace

std::vector<Eigen::Vector2d> Moved(std::span<const Eigen::Vector2d> x, const Eigen::VectorXd& du) {
  std::vector<Eigen::Vector2d> out(x.begin(), x.end());
  for (std::size_t a = 0; a < out.size(); ++a) out[a] += du.segment<2>(2 * a);
  return out;
}

absl::StatusOr<std::vector<PointGeometry>> EvaluateGeometry(const Mesh& mesh,
                                                            std::span<const Eigen::Vector2d> x) {
  std::vector<PointGeometry> out;
  for (int e = 0; e < static_cast<int>(mesh.elements.size()); ++e) {
    const ElementType type = mesh.elements[e].type;
    const ElementCoordinates c = ElementPositions(mesh, e, x);
    for (int p = 0; p < GaussPointCount(type); ++p) {
      absl::StatusOr<PointGeometry> g = EvaluatePoint(type, c, p, e);
      if (!g.ok()) return g.status();
      out.push_back(*std::move(g));
    }
  }
  return out;
}

std::vector<Eigen::Matrix3d> DeformationIncrements(const Mesh& mesh,
                                                   std::span<const PointGeometry> reference,
                                                   const Eigen::VectorXd& du) {
  std::vector<Eigen::Matrix3d> out;
  out.reserve(reference.size());
  std::size_t g = 0;
  for (int e = 0; e < static_cast<int>(mesh.elements.size()); ++e) {
    const std::vector<int>& nodes = mesh.elements[e].nodes;
    for (int p = 0; p < GaussPointCount(mesh.elements[e].type); ++p, ++g) {
      Eigen::Matrix3d f = Eigen::Matrix3d::Identity();
      for (std::size_t a = 0; a < nodes.size(); ++a) {
        f.topLeftCorner<2, 2>() +=
            du.segment<2>(2 * nodes[a]) * reference[g].gradient.row(static_cast<int>(a));
      }
      out.push_back(f);
    }
  }
  return out;
}

Eigen::VectorXd InternalForces(const Mesh& mesh, std::span<const PointGeometry> current,
                               std::span<const PointResponse> responses) {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(2 * static_cast<Eigen::Index>(mesh.nodes.size()));
  std::size_t g = 0;
  for (int e = 0; e < static_cast<int>(mesh.elements.size()); ++e) {
    const std::vector<int>& nodes = mesh.elements[e].nodes;
    for (int p = 0; p < GaussPointCount(mesh.elements[e].type); ++p, ++g) {
      const Eigen::Matrix2d sigma = responses[g].stress.topLeftCorner<2, 2>();
      for (std::size_t a = 0; a < nodes.size(); ++a) {
        f.segment<2>(2 * nodes[a]) +=
            current[g].volume * sigma * current[g].gradient.row(static_cast<int>(a)).transpose();
      }
    }
  }
  return f;
}

Eigen::VectorXd PressureForces(int dofs, std::span<const PressureLoad> pressures,
                               std::span<const Eigen::Vector2d> x) {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(dofs);
  const Eigen::Matrix2d q = Clockwise();
  for (const PressureLoad& load : pressures) {
    for (const Edge& edge : load.edges) {
      const int n = static_cast<int>(edge.nodes.size());
      const Eigen::Matrix3d w = EdgeMoments(n);
      // f_a = −p ∫ N_a n ds = −p Σ_b W_ab Q x_b (compression positive).
      for (int a = 0; a < n; ++a) {
        for (int b = 0; b < n; ++b) {
          f.segment<2>(2 * edge.nodes[a]) -= load.pressure * w(a, b) * q * x[edge.nodes[b]];
        }
      }
    }
  }
  return f;
}

Eigen::SparseMatrix<double> TangentStiffness(const Mesh& mesh,
                                             std::span<const PointGeometry> reference,
                                             std::span<const PointGeometry> current,
                                             std::span<const PointResponse> responses,
                                             std::span<const Tangent> tangents,
                                             std::span<const PressureLoad> pressures,
                                             std::span<const Eigen::Vector2d> x) {
  const int dofs = 2 * static_cast<int>(x.size());
  std::vector<Eigen::Triplet<double>> t;
  std::size_t g = 0;
  for (int e = 0; e < static_cast<int>(mesh.elements.size()); ++e) {
    const std::vector<int>& nodes = mesh.elements[e].nodes;
    const int n = static_cast<int>(nodes.size());
    Eigen::MatrixXd ke = Eigen::MatrixXd::Zero(2 * n, 2 * n);
    for (int p = 0; p < GaussPointCount(mesh.elements[e].type); ++p, ++g) {
      const ShapeGradient& gx = current[g].gradient;    // ∇_x N
      const ShapeGradient& gr = reference[g].gradient;  // ∇_X N
      const Eigen::Matrix2d sigma = responses[g].stress.topLeftCorner<2, 2>();
      const Tangent& d = tangents[g];
      const double dv = current[g].volume;
      for (int a = 0; a < n; ++a) {
        const Eigen::Vector2d sa = sigma * gx.row(a).transpose();
        for (int b = 0; b < n; ++b) {
          const Eigen::Vector2d sb = sigma * gx.row(b).transpose();
          for (int i = 0; i < 2; ++i) {
            for (int k = 0; k < 2; ++k) {
              // Material: ∂N_a/∂x_j D_ijkl ∂N_b/∂X_l. Initial stress: from
              // d(dv) = tr(∇_x δu) dv and d(∇_x N) = −(∇_x δu)ᵀ ∇_x N.
              double m = 0.0;
              for (int j = 0; j < 2; ++j) {
                for (int l = 0; l < 2; ++l) {
                  m += gx(a, j) * d(TangentIndex(i, j), TangentIndex(k, l)) * gr(b, l);
                }
              }
              ke(2 * a + i, 2 * b + k) += dv * (m + sa[i] * gx(b, k) - sb[i] * gx(a, k));
            }
          }
        }
      }
    }
    for (int r = 0; r < 2 * n; ++r) {
      for (int c = 0; c < 2 * n; ++c) {
        t.emplace_back(2 * nodes[r / 2] + r % 2, 2 * nodes[c / 2] + c % 2, ke(r, c));
      }
    }
  }
  // Load stiffness: −∂f_ext,a/∂x_b = p W_ab Q.
  const Eigen::Matrix2d q = Clockwise();
  for (const PressureLoad& load : pressures) {
    for (const Edge& edge : load.edges) {
      const int n = static_cast<int>(edge.nodes.size());
      const Eigen::Matrix3d w = EdgeMoments(n);
      for (int a = 0; a < n; ++a) {
        for (int b = 0; b < n; ++b) {
          for (int i = 0; i < 2; ++i) {
            for (int k = 0; k < 2; ++k) {
              t.emplace_back(2 * edge.nodes[a] + i, 2 * edge.nodes[b] + k,
                             load.pressure * w(a, b) * q(i, k));
            }
          }
        }
      }
    }
  }
  Eigen::SparseMatrix<double> k(dofs, dofs);
  k.setFromTriplets(t.begin(), t.end());  // sums duplicates
  return k;
}

}  // namespace rvehub::fem
