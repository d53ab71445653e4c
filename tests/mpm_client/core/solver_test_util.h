// Set-ups the MPM solver tests share: blocks of points, walls, loads, test
// materials, and stepping a solver. SI units throughout.
#ifndef RVEHUB_TESTS_MPM_CLIENT_CORE_SOLVER_TEST_UTIL_H_
#define RVEHUB_TESTS_MPM_CLIENT_CORE_SOLVER_TEST_UTIL_H_

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "mpm_client/core/model.h"
#include "mpm_client/core/solver.h"

namespace rvehub::mpm {

// A material that never carries stress.
class ZeroStressModel : public StressModel {
 public:
  absl::Status Update(std::int64_t, std::span<const Eigen::Matrix3d>,
                      std::span<PointResponse> out) override {
    for (PointResponse& r : out) r = PointResponse();
    return absl::OkStatus();
  }
};

// A material that reports a fixed void ratio and records the ΔF it gets.
class RecordingModel : public StressModel {
 public:
  explicit RecordingModel(double void_ratio) : void_ratio_(void_ratio) {}
  absl::Status Update(std::int64_t, std::span<const Eigen::Matrix3d> delta_f,
                      std::span<PointResponse> out) override {
    last_.assign(delta_f.begin(), delta_f.end());
    for (PointResponse& r : out) {
      r = PointResponse();
      r.void_ratio = void_ratio_;
    }
    return absl::OkStatus();
  }
  const std::vector<Eigen::Matrix3d>& last() const { return last_; }

 private:
  double void_ratio_;
  std::vector<Eigen::Matrix3d> last_;
};

// Each point's stress fixed (Pa), whatever its increment; the increments
// recorded.
class FixedStressModel : public StressModel {
 public:
  explicit FixedStressModel(std::vector<Eigen::Matrix3d> stress) : stress_(std::move(stress)) {}
  absl::Status Update(std::int64_t, std::span<const Eigen::Matrix3d> delta_f,
                      std::span<PointResponse> out) override {
    last_.assign(delta_f.begin(), delta_f.end());
    for (std::size_t p = 0; p < out.size(); ++p) {
      out[p] = PointResponse();
      out[p].stress = stress_[p];
      out[p].void_ratio = 0.2;
    }
    return absl::OkStatus();
  }
  const std::vector<Eigen::Matrix3d>& last() const { return last_; }

 private:
  std::vector<Eigen::Matrix3d> stress_;
  std::vector<Eigen::Matrix3d> last_;
};

// One region "soil" [lower, upper] (m) of density rho (kg/m³) on a grid of
// nx × ny cells of size h (m) at the origin.
inline CaseSpec BlockCase(double h, int nx, int ny, Eigen::Vector2d lower, Eigen::Vector2d upper,
                          int ppc, double rho = 2000.0) {
  CaseSpec spec;
  spec.grid.cell_size = h;
  spec.grid.nx = nx;
  spec.grid.ny = ny;
  MaterialRegion region;
  region.name = "soil";
  region.lower = lower;
  region.upper = upper;
  region.points_per_cell_side = ppc;
  region.density = rho;
  spec.regions.push_back(region);
  return spec;
}

// A traction (Pa) on region "soil"'s face with outward normal ±axis.
inline SurfaceTraction FaceLoad(const std::string& name, int axis, int sign,
                                const Eigen::Vector2d& traction) {
  SurfaceTraction t;
  t.name = name;
  t.region = "soil";
  t.normal_axis = axis;
  t.normal_sign = sign;
  t.traction = traction;
  return t;
}

inline Wall MakeWall(int axis, double position, ContactKind contact, double mu = 0.0) {
  Wall w;
  w.name = absl::StrCat("wall", axis, "_", position);
  w.axis = axis;
  w.position = position;
  w.contact = contact;
  w.friction = mu;
  return w;
}

// A rough base at y = 0 and smooth walls at x = 0 and x = width (m).
inline std::vector<Wall> BoxWalls(double width) {
  Wall base, left, right;
  base.name = "base";
  base.axis = 1;
  base.contact = ContactKind::kRough;
  left.name = "left";
  left.axis = 0;
  right = left;
  right.name = "right";
  right.position = width;
  return {base, left, right};
}

// A rough rectangle of half size `half` (m) centred at `center`, moving at a
// constant `velocity` (m/s).
inline RigidBody RoughBlock(const std::string& name, const Eigen::Vector2d& center,
                            const Eigen::Vector2d& half, const Eigen::Vector2d& velocity) {
  RigidBody body;
  body.name = name;
  body.center = center;
  body.half_size = half;
  body.contact = ContactKind::kRough;
  body.velocity = {{0.0, velocity}};
  return body;
}

// The case's points, every one at velocity[0] (m/s) when one is given, in a
// new solver; null (and a test failure) when the case is refused. The points
// as filled are copied to `points_out` when it is not null.
inline std::unique_ptr<Solver> MakeSolver(const CaseSpec& spec, StressModel* model,
                                          const std::vector<Eigen::Vector2d>& velocity = {},
                                          MaterialPoints* points_out = nullptr) {
  absl::StatusOr<MaterialPoints> points = FillRegions(spec);
  EXPECT_TRUE(points.ok()) << points.status();
  if (!points.ok()) return nullptr;
  for (std::size_t p = 0; p < points->size() && !velocity.empty(); ++p) {
    points->velocity[p] = velocity[0];
  }
  if (points_out != nullptr) *points_out = *points;
  absl::StatusOr<std::unique_ptr<Solver>> solver = Solver::Create(spec, *std::move(points), model);
  EXPECT_TRUE(solver.ok()) << solver.status();
  return solver.ok() ? *std::move(solver) : nullptr;
}

inline void RunSteps(Solver& solver, int steps) {
  for (int i = 0; i < steps; ++i) {
    const absl::Status s = solver.Step();
    ASSERT_TRUE(s.ok()) << "step " << solver.step() << ": " << s;
  }
}

// Steps until the step count is the one nearest time `t` (s).
inline void RunTo(Solver& solver, double t) {
  RunSteps(solver, static_cast<int>(std::round(t / solver.dt())) - solver.step());
}

// Σ m v, kg·m/s per unit thickness.
inline Eigen::Vector2d Momentum(const MaterialPoints& mp) {
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  for (std::size_t p = 0; p < mp.size(); ++p) sum += mp.mass[p] * mp.velocity[p];
  return sum;
}

// Σ m, kg per unit thickness.
inline double TotalMass(const MaterialPoints& mp) {
  double m = 0.0;
  for (double x : mp.mass) m += x;
  return m;
}

// Geostatic stress (Pa) of a block of height top (m) under gravity g (m/s²),
// K0 from ν.
inline std::vector<Eigen::Matrix3d> Geostatic(const MaterialPoints& mp, double rho, double g,
                                              double top, double nu) {
  std::vector<Eigen::Matrix3d> s(mp.size(), Eigen::Matrix3d::Zero());
  for (std::size_t p = 0; p < mp.size(); ++p) {
    const double sv = -rho * g * (top - mp.position[p].y());
    s[p](1, 1) = sv;
    s[p](0, 0) = s[p](2, 2) = nu / (1.0 - nu) * sv;
  }
  return s;
}

}  // namespace rvehub::mpm

#endif  // RVEHUB_TESTS_MPM_CLIENT_CORE_SOLVER_TEST_UTIL_H_
