// Minimal PNG line plots (cairo) for the tools that plot (rve_cli, mpm_client):
// a grid of panels, each with nice axis ticks, a title, axis labels and a legend.

#ifndef RVEHUB_TOOLKIT_PLOT_H_
#define RVEHUB_TOOLKIT_PLOT_H_

#include <string>
#include <vector>

#include "absl/status/status.h"

namespace rvehub::plot {

// One polyline; x and y must have equal sizes and finite values.
struct Series {
  std::string label;
  std::vector<double> x, y;
};

struct Panel {
  std::string title, x_label, y_label;
  std::vector<Series> series;
};

// Panels fill the grid row by row. The image is
// min(columns, panels) * panel_width wide and rows * panel_height tall.
struct Layout {
  int columns = 2;
  int panel_width = 520;
  int panel_height = 380;
};

// Writes `panels` in a grid to the PNG file `path`.
// Errors: InvalidArgument for no panels, a bad layout, a series whose x and y
// sizes differ or a non-finite value (the message names the series);
// Unavailable (message names `path`) when the file cannot be written.
absl::Status WritePng(const std::string& path, const std::vector<Panel>& panels,
                      const Layout& layout = {});

}  // namespace rvehub::plot

#endif  // RVEHUB_TOOLKIT_PLOT_H_
