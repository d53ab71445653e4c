// The plain values of a batch call on RVEs, shared by the server's registry
// and every client endpoint (embedded or gRPC), so that an outcome passes
// from one to the other without a copy: increments in, per-RVE outcomes out,
// initial stresses of new RVEs. No gRPC and no registry internals: the
// client library may include this header (tests/layering_test.cc).
#ifndef RVEHUB_RVE_SERVER_SERVICE_RVE_BATCH_H_
#define RVEHUB_RVE_SERVER_SERVICE_RVE_BATCH_H_

#include <Eigen/Dense>
#include <cstdint>

#include "absl/status/status.h"
#include "rve_server/engine/rve.h"

namespace rvehub {

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
  dem::RveState state;    // stress tension-positive, Pa (see rve.h)
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

}  // namespace rvehub

#endif  // RVEHUB_RVE_SERVER_SERVICE_RVE_BATCH_H_
