// Hosted RVEs keyed by (run id, material-point id) and packing templates: what
// servers export and import, the store saves and clients keep as recovery
// points. Plain data over RveSnapshot (which holds every bit an RVE needs for
// a bit-exact continuation).
#ifndef RVEHUB_RVE_SERVER_VALUES_RECORD_H_
#define RVEHUB_RVE_SERVER_VALUES_RECORD_H_

#include <Eigen/Dense>
#include <cstdint>
#include <string>
#include <vector>

#include "rve_server/values/snapshot.h"

namespace rvehub {

// Committed steps lie in 0..kMaxStep (2^53): far beyond any run, and exact
// in a double, as clients that read them as numbers (JSON, Python) hold
// them. A record past it is tampered with or corrupt.
inline constexpr std::int64_t kMaxStep = std::int64_t{1} << 53;

// One hosted RVE.
struct RveRecord {
  std::string run_id;     // run that owns the RVE (isolates simulations)
  std::int64_t id = 0;    // material-point id within the run
  std::int64_t step = 0;  // last committed step (0 right after creation), 0..kMaxStep
  // ΔF of the last committed step (identity at step 0), kept so that a retried
  // COMMIT can be checked against it after a restart. 3×3, [-].
  Eigen::Matrix3d last_delta_f = Eigen::Matrix3d::Identity();
  dem::RveSnapshot packing;
};

// A prepared packing plus its material, from which RVEs are created.
struct TemplateRecord {
  std::string name;
  std::string description;  // free text (how it was prepared)
  dem::RveSnapshot packing;
};

// A template as a server summarises it (ListTemplates, UploadTemplate).
struct TemplateInfo {
  std::string name;
  std::string description;
  std::string material_name;
  std::int64_t num_particles = 0;
  double void_ratio = 0.0;     // [-]
  double mean_pressure = 0.0;  // p, Pa, compression +
};

// One hosted run (ListRuns).
struct RunInfo {
  std::string run_id;
  std::int64_t num_rves = 0;
  std::int64_t min_step = 0;  // smallest committed step of its RVEs
  std::int64_t max_step = 0;  // largest
};

}  // namespace rvehub

#endif  // RVEHUB_RVE_SERVER_VALUES_RECORD_H_
