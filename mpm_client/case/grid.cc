// The case's "grid" section, and its grid lines (walls, region corners and
// drained boundaries lie on them).
#include <cmath>
#include <cstdint>
#include <string>

#include "absl/status/status.h"
#include "mpm_client/case/sections.h"

namespace rvehub::mpm::case_internal {
namespace {

// Coordinates within this fraction of a cell of a grid line are on it (and
// snapped onto it): decimal inputs such as 0.3 with h = 0.1 are not exact.
constexpr double kGridTolerance = 1e-6;

// Bounded so that node and cell counts fit an int.
constexpr int kMaxCells = 100000;
constexpr std::int64_t kMaxTotalCells = 100000000;

Fields<GridSpec> GridFields() {
  return {
      Vec2Field("origin", &GridSpec::origin, Need::kOptional, kAny),
      NumberField("cell_size", &GridSpec::cell_size, Need::kRequired, kPositive),
      {"cells",
       [](const Object& o, GridSpec* grid) -> absl::Status {
         const Json* cells = o.Get("cells");
         if (cells == nullptr) return o.Missing("cells");
         if (!cells->is_array() || cells->size() != 2) {
           return Bad(o.At("cells"), "must be an array of 2 integers [nx, ny], got ", Got(*cells));
         }
         RETURN_IF_ERROR(ReadInt((*cells)[0], Child(o.At("cells"), 0), 1, kMaxCells, &grid->nx));
         RETURN_IF_ERROR(ReadInt((*cells)[1], Child(o.At("cells"), 1), 1, kMaxCells, &grid->ny));
         if (static_cast<std::int64_t>(grid->nx) * grid->ny > kMaxTotalCells) {
           return Bad(o.At("cells"), "at most ", kMaxTotalCells, " cells, got ", grid->nx, " × ",
                      grid->ny);
         }
         return absl::OkStatus();
       },
       [](const GridSpec& g, OrderedJson& j) {
         j["cells"] = OrderedJson::array({g.nx, g.ny});
       }},
  };
}

}  // namespace

const Table<int> kAxes = {{"x", 0}, {"y", 1}};
absl::string_view AxisName(int axis) { return kAxisName[axis == 0 ? 0 : 1]; }

absl::Status GridLines::Snap(double x, int axis, absl::string_view ptr, int* index,
                             double* snapped) const {
  const double origin = grid_.origin[axis];
  const int n = axis == 0 ? grid_.nx : grid_.ny;
  const double k = (x - origin) / grid_.cell_size;
  const double i = std::round(k);
  if (std::abs(k - i) > kGridTolerance) {
    return Bad(ptr, kAxisName[axis], " = ", Num(x), " m is not on a grid line (origin ",
               Num(origin), " m, cell size ", Num(grid_.cell_size), " m)");
  }
  if (i < 0 || i > n) {
    return Bad(ptr, kAxisName[axis], " = ", Num(x), " m is outside the grid, ", kAxisName[axis],
               " in [", Num(origin), ", ", Num(origin + n * grid_.cell_size), "] m");
  }
  *index = static_cast<int>(i);
  *snapped = origin + *index * grid_.cell_size;
  return absl::OkStatus();
}

absl::Status ParseGrid(const Json& j, const std::string& ptr, GridSpec* grid) {
  return ReadFields(j, ptr, GridFields(), grid).status();
}

OrderedJson WriteGrid(const GridSpec& grid) { return WriteFields(GridFields(), grid); }

}  // namespace rvehub::mpm::case_internal
