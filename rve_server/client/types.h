// Plain values a client exchanges with RVE servers, whichever endpoint
// carries them (embedded registry or gRPC): increments, per-RVE outcomes and
// initial stresses. No server types: a client builds against these alone.
#ifndef RVEHUB_RVE_SERVER_CLIENT_TYPES_H_
#define RVEHUB_RVE_SERVER_CLIENT_TYPES_H_

#include <Eigen/Dense>
#include <cstdint>
#include <functional>

#include "absl/status/status.h"
#include "rve_server/engine/rve.h"
#include "store/record.h"

namespace rvehub::client {

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
  // Engine wall time for this RVE in the call, s: a measurement for load
  // figures, never part of a state.
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

// Receives exported RVE states one at a time; an error stops the export.
using RecordSink = std::function<absl::Status(store::RveRecord&&)>;

}  // namespace rvehub::client

#endif  // RVEHUB_RVE_SERVER_CLIENT_TYPES_H_
