// Set-ups the fem_client/core tests share: distorted meshes and uniform
// stresses.
#ifndef RVEHUB_TESTS_FEM_CLIENT_CORE_FEM_TEST_UTIL_H_
#define RVEHUB_TESTS_FEM_CLIENT_CORE_FEM_TEST_UTIL_H_

#include <Eigen/Dense>
#include <algorithm>
#include <functional>
#include <span>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "fem_client/core/boundary.h"
#include "fem_client/core/material.h"
#include "fem_client/core/mesh.h"

namespace rvehub::fem::testing {

// A 2 m × 2 m square of 2 × 2 elements whose interior node is moved off
// the centre, so that no element is a parallelogram; Q8's midsides on the
// interior edges are moved off their chords too (curved edges). The
// boundary stays straight.
inline Mesh DistortedSquare(ElementType type) {
  RectangleSpec spec;
  spec.width = spec.height = 2.0;
  spec.nx = spec.ny = 2;
  spec.type = type;
  Mesh mesh = *StructuredRectangle(spec);
  const Eigen::Vector2d centre(1.0, 1.0), moved(1.23, 0.84);
  for (Eigen::Vector2d& x : mesh.nodes) {
    if ((x - centre).norm() < 1e-12) x = moved;
  }
  if (type != ElementType::kQ4) {
    // Midsides of the four interior edges: halfway to the moved centre,
    // then off the chord.
    const Eigen::Vector2d ends[4] = {{1.0, 0.0}, {2.0, 1.0}, {1.0, 2.0}, {0.0, 1.0}};
    const Eigen::Vector2d bend[4] = {{0.04, 0.0}, {0.0, -0.05}, {-0.03, 0.0}, {0.0, 0.06}};
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector2d old_mid = 0.5 * (ends[k] + centre);
      for (Eigen::Vector2d& x : mesh.nodes) {
        if ((x - old_mid).norm() < 1e-12) x = 0.5 * (ends[k] + moved) + bend[k];
      }
    }
  }
  return mesh;
}

// A width × height (m) rectangle of nx × ny elements of `type`.
inline Mesh Rectangle(double width, double height, int nx, int ny, ElementType type) {
  RectangleSpec spec;
  spec.width = width;
  spec.height = height;
  spec.nx = nx;
  spec.ny = ny;
  spec.type = type;
  return *StructuredRectangle(spec);
}

// One stress (Pa) for every Gauss point of the mesh: a stand-in's initial state.
inline std::vector<Eigen::Matrix3d> Uniform(const Mesh& mesh, const Eigen::Matrix3d& s) {
  return std::vector<Eigen::Matrix3d>(CountGaussPoints(mesh), s);
}

// The nodes in no node set: the interior.
inline std::vector<int> InteriorNodes(const Mesh& mesh) {
  std::vector<bool> boundary(mesh.nodes.size(), false);
  for (const auto& [name, ids] : mesh.node_sets) {
    for (int id : ids) boundary[id] = true;
  }
  std::vector<int> out;
  for (int a = 0; a < static_cast<int>(mesh.nodes.size()); ++a) {
    if (!boundary[a]) out.push_back(a);
  }
  return out;
}

// The patch test's boundary: every node outside InteriorNodes moved by
// h·x over each step (a uniform gradient h), the interior free.
inline Boundary PatchBoundary(const Mesh& mesh, const Eigen::Matrix2d& h) {
  const std::vector<int> interior = InteriorNodes(mesh);
  Boundary b;
  for (int a = 0; a < static_cast<int>(mesh.nodes.size()); ++a) {
    if (std::find(interior.begin(), interior.end(), a) != interior.end()) continue;
    const Eigen::Vector2d du = h * mesh.nodes[a];
    b.prescribed.push_back({a, 0, du.x()});
    b.prescribed.push_back({a, 1, du.y()});
  }
  return b;
}

inline Eigen::Matrix3d InPlane(const Eigen::Matrix2d& a) {
  Eigen::Matrix3d m = Eigen::Matrix3d::Identity();
  m.topLeftCorner<2, 2>() = a;
  return m;
}

// Anisotropic, with shear: what a consolidated packing may carry, Pa.
inline Eigen::Matrix3d Prestress() {
  Eigen::Matrix3d s = Eigen::Matrix3d::Zero();
  s(0, 0) = -2e5;
  s(1, 1) = -1e5;
  s(0, 1) = s(1, 0) = 3e4;
  s(2, 2) = -1.5e5;
  return s;
}

// Forwards to a material, counting the calls and keeping the last committed
// ΔF; `fail` (when set) may refuse a Trial, and `drop_tangents` strips them.
class SpyMaterial : public GaussPointMaterial {
 public:
  explicit SpyMaterial(GaussPointMaterial* inner) : inner_(inner) {}

  absl::StatusOr<std::vector<PointResponse>> Trial(std::span<const Eigen::Matrix3d> delta_f,
                                                   bool want_tangent) override {
    ++trials;
    tangent_trials += want_tangent;
    if (fail) {
      if (absl::Status s = fail(delta_f); !s.ok()) return s;
    }
    absl::StatusOr<std::vector<PointResponse>> r = inner_->Trial(delta_f, want_tangent);
    if (r.ok() && drop_tangents) {
      for (PointResponse& p : *r) p.tangent.reset();
    }
    return r;
  }
  absl::Status Commit(std::span<const Eigen::Matrix3d> delta_f) override {
    ++commits;
    last_commit.assign(delta_f.begin(), delta_f.end());
    return inner_->Commit(delta_f);
  }

  std::function<absl::Status(std::span<const Eigen::Matrix3d>)> fail;
  bool drop_tangents = false;
  int trials = 0, tangent_trials = 0, commits = 0;
  std::vector<Eigen::Matrix3d> last_commit;

 private:
  GaussPointMaterial* inner_;
};

}  // namespace rvehub::fem::testing

#endif  // RVEHUB_TESTS_FEM_CLIENT_CORE_FEM_TEST_UTIL_H_
