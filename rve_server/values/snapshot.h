// RveSnapshot, the complete state of one RVE as a plain struct (particles,
// contact history, cell, material, controls and counters; a "packing" is only
// its particle part): what the engine restores, the store saves and the wire
// carries. Restoring it gives a bit-identical continuation. With the ranges
// every layer checks it against.
#ifndef RVEHUB_RVE_SERVER_VALUES_SNAPSHOT_H_
#define RVEHUB_RVE_SERVER_VALUES_SNAPSHOT_H_

#include <Eigen/Dense>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "absl/status/status.h"
#include "rve_server/values/material.h"

namespace rvehub::dem {

// Numerical controls of one RVE (configurable per RVE, checked on creation).
struct Controls {
  double time_step_factor = 0.5;      // Δt = factor·sqrt(m_min/kn_max), [-]
  double max_inertial_number = 1e-3;  // I = γ̇·d_mean·sqrt(ρ/p) bound for Apply, [-]
  double pressure_floor = 1e3;        // Pa; p used in I when the RVE is looser than this
  std::int64_t min_steps = 20;  // DEM steps per Apply at least (0: an identity ΔF takes none)
  double max_stretch = 0.05;    // per-Apply bound on |V − I| (Frobenius), [-]
  double max_rotation = 0.5;    // per-Apply bound on the rigid rotation, rad
  double mass_scale = 1.0;      // density scaling λ ≥ 1 for quasi-static work, [-]
  double skin = 0.25;           // Verlet skin as a fraction of the smallest radius, [-]
};

// History of one contact (or bonded pair), keyed by particle indices i < j.
struct ContactHistory {
  std::uint32_t i = 0;
  std::uint32_t j = 0;
  double tangential_force = 0.0;  // ft, N, along t = (−n_y, n_x), n from i to j
  double rolling_moment = 0.0;    // M_r acting on i (−M_r on j), N·m
  double bond_strength = 0.0;     // N; > 0 while the pair is bonded
};

struct RveSnapshot {
  Material material;
  Controls controls;
  // Cell matrix h (m): columns are the two cell vectors; x = h·s.
  Eigen::Matrix2d cell = Eigen::Matrix2d::Identity();
  // The cell of the reference configuration written in the current lattice
  // basis (cell flips change both alike), so F = cell·reference_cell⁻¹ is the
  // deformation gradient since the reference, whatever flips happened.
  Eigen::Matrix2d reference_cell = Eigen::Matrix2d::Identity();
  // Accumulated rigid rotation of the cell; local damping acts in this frame
  // so that a rigid rotation of the RVE is exactly objective.
  Eigen::Matrix2d frame = Eigen::Matrix2d::Identity();
  std::vector<double> radius;             // m
  std::vector<double> sx, sy;             // reduced coordinates, [-] (not wrapped)
  std::vector<double> vx, vy;             // fluctuating velocity (total − L·x), m/s
  std::vector<double> omega;              // angular velocity, rad/s (counter-clockwise +)
  std::vector<double> theta;              // accumulated rotation, rad
  std::vector<ContactHistory> contacts;   // sorted by (i, j)
  double initial_void_ratio = 0.0;        // e0, [-]
  double permeability_coefficient = 0.0;  // c in k = c·e³/(1+e), m/s
  std::int64_t total_steps = 0;           // DEM steps since creation, 0..kMaxTotalSteps
};

// Ranges (see also rve_service.proto): time_step_factor (0, 1],
// max_inertial_number [1e-6, 1], pressure_floor [1, 1e9] Pa, min_steps
// [0, 1e6], max_stretch (0, 10], max_rotation (0, π/2] rad, mass_scale ≥ 1,
// skin (0, 2]. They bound the DEM steps one increment may take.
inline constexpr double kMinPressureFloor = 1.0;  // Pa
inline constexpr double kMaxPressure = 1e9;       // Pa, any stress target or floor
inline constexpr std::int64_t kMaxMinSteps = 1'000'000;
inline constexpr double kMinInertialNumber = 1e-6;  // any inertial number bound, [-]
inline constexpr double kMaxInertialNumber = 1.0;
absl::Status Validate(const Controls& c);

// Limits on a packing's size, so that a malformed or hostile packing cannot
// ask for unbounded memory or time (the neighbour grid grows with the cell
// area over the squared particle size); the engine's ValidatePacking applies
// them on every path (templates, imports, checkpoints).
inline constexpr std::size_t kMaxParticles = 1'000'000;
inline constexpr double kMaxGridCellsPerParticle = 1000;  // ≈ solid fraction ≥ 6e-4
inline constexpr double kMinGridCells = 1e4;
inline constexpr std::size_t kMaxNameBytes = 128;  // material name, printable ASCII
// DEM steps since creation at most (2^53, exact in a double): centuries of
// stepping; a count past it is tampered with or corrupt.
inline constexpr std::int64_t kMaxTotalSteps = std::int64_t{1} << 53;

// Σ π r², the discs' own area, m² (overlaps not taken out).
double SolidArea(const std::vector<double>& radius);

}  // namespace rvehub::dem

#endif  // RVEHUB_RVE_SERVER_VALUES_SNAPSHOT_H_
