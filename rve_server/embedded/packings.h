// Work on single packings in a client's own process, offered in values so
// that clients need not know the engine: preparing a template from a named
// parameter set (rve_cli prepare, mpm_client's and fem_client's case
// templates), observing a packing's state and its contact forces, and an
// element test on a local RVE (rve_cli element-test without --server).
#ifndef RVEHUB_RVE_SERVER_EMBEDDED_PACKINGS_H_
#define RVEHUB_RVE_SERVER_EMBEDDED_PACKINGS_H_

#include <Eigen/Dense>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "rve_server/values/element_test.h"
#include "rve_server/values/preparation.h"
#include "rve_server/values/record.h"
#include "rve_server/values/state.h"

namespace rvehub::embedded {

// The one way to make a template from a named parameter set and a seed:
// the engine's PrepareTemplate (engine/prepare.h: its errors and ranges),
// named by TemplateName and described by TemplateDescription
// (values/preparation.h). `report`, when given, receives the preparation's
// report; `progress` its lines, the first "N discs, seed S".
absl::StatusOr<TemplateRecord> PrepareTemplate(
    absl::string_view parameter_set, std::uint64_t seed, const dem::TemplateVariant& variant = {},
    dem::PreparationReport* report = nullptr,
    const std::function<void(const std::string&)>& progress = {});

// The homogenised state of a packing as it is (the tangent when asked).
// InvalidArgument for a packing the engine refuses (ValidatePacking).
absl::StatusOr<dem::RveState> Observe(const dem::RveSnapshot& packing, bool want_tangent);

// One active contact of a packing, as the engine's force law gives it.
struct PackingContact {
  std::uint32_t i = 0, j = 0;                        // disc indices
  Eigen::Vector2d branch = Eigen::Vector2d::Zero();  // x_j − x_i, nearest image, m
  double normal_force = 0.0;                         // fn, N, compression +
  double tangential_force = 0.0;                     // ft, N, along (−n_y, n_x)
};

// A packing's discs and contact forces as it is: for force-chain plots.
struct PackingForces {
  Eigen::Matrix2d cell = Eigen::Matrix2d::Identity();  // columns: the cell vectors, m
  std::vector<Eigen::Vector2d> position;  // each disc's centre wrapped into the cell, m
  std::vector<double> radius;             // m
  std::vector<PackingContact> contacts;   // sorted by (i, j)
};

// The discs and contacts of `packing` (InvalidArgument for a packing the
// engine refuses, as Observe).
absl::StatusOr<PackingForces> ContactForces(const dem::RveSnapshot& packing);

// Runs `spec` on an RVE made from `packing` (engine/element_test.h: the
// ranges, the consolidation first, the rows). `progress` sees the fraction
// done, 0..1.
absl::StatusOr<std::vector<dem::ElementTestRow>> RunElementTest(
    dem::RveSnapshot packing, const dem::ElementTestSpec& spec,
    const std::function<void(double)>& progress = {});

}  // namespace rvehub::embedded

#endif  // RVEHUB_RVE_SERVER_EMBEDDED_PACKINGS_H_
