// What a step asks of RVEs and gets back, shared by the engine, the server's
// registry, the wire and every client endpoint (embedded or gRPC), so that an
// outcome passes from one to the other without a copy: the options of an
// increment and their ranges, increments in, per-RVE outcomes out, initial
// stresses of new RVEs, and whether a call commits or only tries.
#ifndef RVEHUB_RVE_SERVER_VALUES_INCREMENT_H_
#define RVEHUB_RVE_SERVER_VALUES_INCREMENT_H_

#include <Eigen/Dense>
#include <cstdint>

#include "absl/status/status.h"
#include "rve_server/values/state.h"

namespace rvehub {
namespace dem {

// The options of one increment (Rve::Apply; rve_service.proto ApplyOptions).
struct ApplyOptions {
  bool relax = false;             // after the increment, relax at fixed cell
  double relax_tolerance = 1e-4;  // unbalanced-force ratio to stop relaxing
  std::int64_t relax_max_steps = 20000;
  bool want_tangent = false;
  // Tighter bound on the inertial number for this call, [-]; 0 (or a value
  // above the RVE's Controls::max_inertial_number): the RVE's own bound.
  double max_inertial_number = 0.0;
  // Physical duration of the increment, s; > 0: at most ⌈duration/Δt⌉ DEM
  // steps (min_steps still holds), so the RVE never deforms slower than the
  // continuum does. Where the quasi-static bound asks for more (a flowing
  // packing, one near zero pressure) the RVE then follows its own inertial
  // (rate-dependent) response at the continuum's strain rate. 0: no cap.
  double duration = 0.0;
  // Measure the stress alone at the increment's end, for a caller that reads
  // only the stress between its outputs (an MPM step): the state returned
  // carries stress, volume, void ratio, porosity, permeability, steps, Δt,
  // mass scale (and the tangent if asked for) and leaves the fabric, the
  // contact counts and coordinations, the unbalanced-force ratio, the mean
  // rotation and the kinetic energy at zero. The RVE itself evolves exactly
  // as in a full call; a later full observation measures the rest, bit for
  // bit. Saves most of the homogenisation of a one-DEM-step increment.
  bool stress_only = false;
};

// Limits on one call's work, checked before anything changes (the documented
// ranges of the wire contract, see rve_service.proto).
inline constexpr std::int64_t kMaxStepsPerApply = 100'000'000;  // DEM steps of one increment
inline constexpr std::int64_t kMaxRelaxSteps = 10'000'000;      // ApplyOptions::relax_max_steps
inline constexpr double kMinRelaxTolerance = 1e-12;             // ApplyOptions::relax_tolerance
inline constexpr double kMaxDuration = 1e6;                     // s, ApplyOptions::duration

// Ranges of ApplyOptions (relax_tolerance in [1e-12, 1], relax_max_steps in
// [0, 1e7], max_inertial_number 0 or in [1e-6, 1], duration in [0, 1e6] s).
absl::Status Validate(const ApplyOptions& options);

// The checks Apply makes on ΔF before touching anything: 9 finite values,
// plane strain (ΔF_zz = 1, no out-of-plane coupling) and det ΔF > 0.
absl::Status ValidateDeltaF(const Eigen::Matrix3d& delta_f);

}  // namespace dem

// COMMIT advances RVEs by a step; TRIAL computes the same and leaves them as
// they were (rve_service.proto, ApplyRequest).
enum class ApplyMode { kCommit, kTrial };

// One RVE's deformation increment of a step.
struct Increment {
  std::int64_t id = 0;                                    // material-point id
  Eigen::Matrix3d delta_f = Eigen::Matrix3d::Identity();  // ΔF, [-], plane strain
};

// What a batch call says about one RVE.
struct RveOutcome {
  std::int64_t id = 0;
  absl::Status status;    // this RVE's result; the rest is valid when OK
  std::int64_t step = 0;  // the RVE's committed step after the call
  dem::RveState state;    // stress tension-positive, Pa (see state.h)
  Eigen::Matrix3d deformation_gradient = Eigen::Matrix3d::Identity();  // F since creation, [-]
  // Engine wall time for this RVE in the call (Apply: DEM steps and
  // homogenisation), s: a measurement for load figures, never part of a state.
  double engine_seconds = 0.0;
};

// Initial stress of new RVEs, compression-positive (soil mechanics' sign),
// Pa. kTemplate keeps the template's state as it is.
struct InitialStress {
  enum class Kind { kTemplate, kIsotropic, kK0 };
  Kind kind = Kind::kTemplate;
  double pressure = 0.0;              // kIsotropic: p, Pa
  double vertical_compression = 0.0;  // kK0: σv = σyy, Pa
  double k0 = 0.0;                    // kK0: σxx/σyy, [-]
};

// Finite positive stresses (and K0) for the kind; kTemplate is always valid.
absl::Status Validate(const InitialStress& initial);

}  // namespace rvehub

#endif  // RVEHUB_RVE_SERVER_VALUES_INCREMENT_H_
