// What the store saves: RVE states keyed by (run id, material-point id) and
// packing templates. Plain data over the engine's RveSnapshot (which holds every
// bit an RVE needs for a bit-exact continuation).
#ifndef RVEHUB_STORE_RECORD_H_
#define RVEHUB_STORE_RECORD_H_

#include <Eigen/Dense>
#include <cstdint>
#include <string>
#include <vector>

#include "rve_server/engine/snapshot.h"

namespace rvehub::store {

// One hosted RVE.
struct RveRecord {
  std::string run_id;     // run that owns the RVE (isolates simulations)
  std::int64_t id = 0;    // material-point id within the run
  std::int64_t step = 0;  // last committed step (0 right after creation)
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

// File-level facts written into every store file.
struct FileInfo {
  std::string created_by;           // program and version, e.g. "rve_server 0.3.0"
  std::string created_at;           // ISO 8601 UTC
  std::int32_t format_version = 0;  // filled in by the reader
};

}  // namespace rvehub::store

#endif  // RVEHUB_STORE_RECORD_H_
