#include "toolkit/plot.h"

#include <cairo.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "rve_server/common/status_macros.h"

namespace rvehub::plot {
namespace {

struct SurfaceDeleter {
  void operator()(cairo_surface_t* s) const { cairo_surface_destroy(s); }
};
struct ContextDeleter {
  void operator()(cairo_t* cr) const { cairo_destroy(cr); }
};
using SurfacePtr = std::unique_ptr<cairo_surface_t, SurfaceDeleter>;
using ContextPtr = std::unique_ptr<cairo_t, ContextDeleter>;

struct Rgb {
  double r, g, b;
};
// Matplotlib's "tab10" colours: distinct and readable on white.
constexpr Rgb kPalette[] = {{0.12, 0.47, 0.71}, {1.00, 0.50, 0.05}, {0.17, 0.63, 0.17},
                            {0.84, 0.15, 0.16}, {0.58, 0.40, 0.74}, {0.55, 0.34, 0.29},
                            {0.89, 0.47, 0.76}, {0.50, 0.50, 0.50}, {0.74, 0.74, 0.13},
                            {0.09, 0.75, 0.81}};
constexpr int kPaletteSize = sizeof(kPalette) / sizeof(kPalette[0]);

// Space around the plot area inside a panel, in pixels.
// The left margin also grows with the widest y tick label.
constexpr double kLeft = 36, kRight = 24, kTop = 34, kBottom = 50;
constexpr int kMinPanelWidth = 160, kMinPanelHeight = 120;
constexpr int kMaxImageSide = 32767;  // cairo's image surface limit.

// An axis range widened to "nice" tick values (1, 2 or 5 times a power of 10).
struct Axis {
  double lo = 0, hi = 1, step = 0;
  std::vector<double> ticks;
};

Axis NiceAxis(double lo, double hi) {
  if (!(lo <= hi)) lo = 0, hi = 1;  // No data.
  const double mag = std::max(std::abs(lo), std::abs(hi));
  constexpr double kTiny = 1e-290;               // Keeps spans far from subnormal numbers.
  if (hi - lo <= std::max(mag * 1e-9, kTiny)) {  // All values (nearly) equal: pad around them.
    const double pad = mag > kTiny ? mag * 0.1 : 1.0;
    lo = std::max(lo - pad, std::numeric_limits<double>::lowest());
    hi = std::min(hi + pad, std::numeric_limits<double>::max());
  }
  Axis axis;
  const double raw = (hi - lo) / 4;         // Aim for about 5 ticks.
  if (!std::isfinite(raw) || !(raw > 0)) {  // Near the double limits: no nice ticks.
    axis.lo = lo, axis.hi = hi, axis.ticks = {lo, hi};
    return axis;
  }
  const double power = std::pow(10.0, std::floor(std::log10(raw)));
  const double r = raw / power;
  axis.step = power * (r < std::sqrt(2.0)    ? 1
                       : r < std::sqrt(10.0) ? 2
                       : r < std::sqrt(50.0) ? 5
                                             : 10);
  axis.lo = std::floor(lo / axis.step + 1e-9) * axis.step;
  axis.hi = std::ceil(hi / axis.step - 1e-9) * axis.step;
  const long n = std::lround((axis.hi - axis.lo) / axis.step);
  for (long i = 0; i <= n; ++i) {
    double v = axis.lo + static_cast<double>(i) * axis.step;
    if (std::abs(v) < axis.step * 1e-6) v = 0;  // Avoid "-0" and 1e-17.
    axis.ticks.push_back(v);
  }
  return axis;
}

// Formats a tick value with just enough digits to tell neighbours apart.
std::string TickLabel(double v, const Axis& axis) {
  char buf[64];
  const double mag = std::max(std::abs(axis.lo), std::abs(axis.hi));
  const int step_exp =
      axis.step > 0 ? static_cast<int>(std::floor(std::log10(axis.step) + 1e-9)) : 0;
  if (axis.step > 0 && mag < 1e6 && step_exp >= -4) {
    std::snprintf(buf, sizeof(buf), "%.*f", std::max(0, -step_exp), v);
  } else {
    int digits = 3;
    if (axis.step > 0 && mag > 0) {
      digits = std::clamp(static_cast<int>(std::floor(std::log10(mag))) - step_exp + 1, 1, 15);
    }
    std::snprintf(buf, sizeof(buf), "%.*g", digits, v);
  }
  return buf;
}

// Draws `text` with its reference point at (x, y): align_x 0 = left edge,
// 0.5 = centre, 1 = right edge; the text is centred vertically on y.
void Text(cairo_t* cr, const std::string& text, double x, double y, double align_x) {
  cairo_text_extents_t ext;
  cairo_text_extents(cr, text.c_str(), &ext);
  cairo_move_to(cr, x - ext.x_bearing - align_x * ext.width, y - ext.y_bearing - ext.height / 2);
  cairo_show_text(cr, text.c_str());
}

void SetFont(cairo_t* cr, double size, bool bold) {
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL,
                         bold ? CAIRO_FONT_WEIGHT_BOLD : CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, size);
}

void DrawLegend(cairo_t* cr, const Panel& panel, double right, double top) {
  SetFont(cr, 11, false);
  double text_w = 0;
  for (const Series& s : panel.series) {
    cairo_text_extents_t ext;
    cairo_text_extents(cr, s.label.c_str(), &ext);
    text_w = std::max(text_w, ext.x_advance);
  }
  const double row = 16, w = 36 + text_w, h = row * panel.series.size() + 6;
  const double x = right - w - 8, y = top + 8;
  cairo_rectangle(cr, x, y, w, h);
  cairo_set_source_rgba(cr, 1, 1, 1, 0.85);
  cairo_fill_preserve(cr);
  cairo_set_source_rgb(cr, 0.6, 0.6, 0.6);
  cairo_set_line_width(cr, 1);
  cairo_stroke(cr);
  for (size_t i = 0; i < panel.series.size(); ++i) {
    const Rgb& c = kPalette[i % kPaletteSize];
    const double cy = y + 3 + row * (i + 0.5);
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    cairo_set_line_width(cr, 2);
    cairo_move_to(cr, x + 6, cy);
    cairo_line_to(cr, x + 28, cy);
    cairo_stroke(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    Text(cr, panel.series[i].label, x + 32, cy, 0);
  }
}

// Draws one panel with its top-left corner at the current origin.
void DrawPanel(cairo_t* cr, const Panel& panel, double width, double height) {
  double x_min = std::numeric_limits<double>::infinity(), x_max = -x_min;
  double y_min = x_min, y_max = x_max;
  for (const Series& s : panel.series) {
    for (double v : s.x) x_min = std::min(x_min, v), x_max = std::max(x_max, v);
    for (double v : s.y) y_min = std::min(y_min, v), y_max = std::max(y_max, v);
  }
  const Axis xa = NiceAxis(x_min, x_max), ya = NiceAxis(y_min, y_max);
  SetFont(cr, 11, false);
  double y_label_w = 0;
  for (double t : ya.ticks) {
    cairo_text_extents_t ext;
    cairo_text_extents(cr, TickLabel(t, ya).c_str(), &ext);
    y_label_w = std::max(y_label_w, ext.width);
  }
  const double px = std::min(kLeft + y_label_w + 8, width / 2), py = kTop;
  const double pw = width - px - kRight, ph = height - kTop - kBottom;
  // Halves keep the differences finite even for ranges near the double limits.
  auto sx = [&](double v) { return px + (v / 2 - xa.lo / 2) / (xa.hi / 2 - xa.lo / 2) * pw; };
  auto sy = [&](double v) { return py + ph - (v / 2 - ya.lo / 2) / (ya.hi / 2 - ya.lo / 2) * ph; };

  // Grid lines, tick marks and tick labels.
  cairo_set_line_width(cr, 1);
  for (double t : xa.ticks) {
    const double x = std::round(sx(t)) + 0.5;
    cairo_set_source_rgb(cr, 0.9, 0.9, 0.9);
    cairo_move_to(cr, x, py);
    cairo_line_to(cr, x, py + ph);
    cairo_stroke(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    cairo_move_to(cr, x, py + ph);
    cairo_line_to(cr, x, py + ph + 5);
    cairo_stroke(cr);
    const std::string label = TickLabel(t, xa);
    cairo_text_extents_t ext;
    cairo_text_extents(cr, label.c_str(), &ext);
    Text(cr, label, std::min(x, width - 2 - ext.width / 2), py + ph + 15, 0.5);  // Keep inside.
  }
  for (double t : ya.ticks) {
    const double y = std::round(sy(t)) + 0.5;
    cairo_set_source_rgb(cr, 0.9, 0.9, 0.9);
    cairo_move_to(cr, px, y);
    cairo_line_to(cr, px + pw, y);
    cairo_stroke(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    cairo_move_to(cr, px - 5, y);
    cairo_line_to(cr, px, y);
    cairo_stroke(cr);
    Text(cr, TickLabel(t, ya), px - 8, y, 1);
  }
  cairo_rectangle(cr, std::round(px) + 0.5, std::round(py) + 0.5, std::round(pw), std::round(ph));
  cairo_stroke(cr);

  // Title and axis labels.
  SetFont(cr, 14, true);
  Text(cr, panel.title, px + pw / 2, kTop / 2, 0.5);
  SetFont(cr, 12, false);
  Text(cr, panel.x_label, px + pw / 2, height - 14, 0.5);
  cairo_save(cr);
  cairo_translate(cr, 14, py + ph / 2);
  cairo_rotate(cr, -std::numbers::pi / 2);
  Text(cr, panel.y_label, 0, 0, 0.5);
  cairo_restore(cr);

  // The series, clipped to the plot area.
  cairo_save(cr);
  cairo_rectangle(cr, px - 2, py - 2, pw + 4, ph + 4);  // Lines on the frame stay visible.
  cairo_clip(cr);
  cairo_set_line_width(cr, 2);
  cairo_set_line_join(cr, CAIRO_LINE_JOIN_ROUND);
  cairo_set_line_cap(cr, CAIRO_LINE_CAP_ROUND);
  for (size_t i = 0; i < panel.series.size(); ++i) {
    const Series& s = panel.series[i];
    if (s.x.empty()) continue;
    const Rgb& c = kPalette[i % kPaletteSize];
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    const bool one_point = std::equal(s.x.begin() + 1, s.x.end(), s.x.begin()) &&
                           std::equal(s.y.begin() + 1, s.y.end(), s.y.begin());
    if (one_point) {  // A lone point has no line: show it as a dot.
      cairo_arc(cr, sx(s.x[0]), sy(s.y[0]), 3, 0, 2 * std::numbers::pi);
      cairo_fill(cr);
      continue;
    }
    cairo_move_to(cr, sx(s.x[0]), sy(s.y[0]));
    for (size_t k = 1; k < s.x.size(); ++k) cairo_line_to(cr, sx(s.x[k]), sy(s.y[k]));
    cairo_stroke(cr);
  }
  cairo_restore(cr);

  if (panel.series.size() > 1) DrawLegend(cr, panel, px + pw, py);
}

absl::Status Validate(const std::vector<Panel>& panels, const Layout& layout) {
  if (panels.empty()) return absl::InvalidArgumentError("plot: no panels to draw");
  if (layout.columns < 1 || layout.panel_width < kMinPanelWidth ||
      layout.panel_height < kMinPanelHeight) {
    return absl::InvalidArgumentError(
        absl::StrCat("plot: bad layout: columns=", layout.columns, " panel ", layout.panel_width,
                     "x", layout.panel_height, " (need columns >= 1, panel >= ", kMinPanelWidth,
                     "x", kMinPanelHeight, ")"));
  }
  for (const Panel& panel : panels) {
    for (const Series& s : panel.series) {
      const std::string where =
          absl::StrCat("plot: series '", s.label, "' in panel '", panel.title, "'");
      if (s.x.size() != s.y.size()) {
        return absl::InvalidArgumentError(
            absl::StrCat(where, ": x has ", s.x.size(), " values but y has ", s.y.size()));
      }
      for (size_t k = 0; k < s.x.size(); ++k) {
        if (!std::isfinite(s.x[k]) || !std::isfinite(s.y[k])) {
          return absl::InvalidArgumentError(absl::StrCat(where, ": non-finite value at index ", k));
        }
      }
    }
  }
  return absl::OkStatus();
}

}  // namespace

absl::Status WritePng(const std::string& path, const std::vector<Panel>& panels,
                      const Layout& layout) {
  RETURN_IF_ERROR(Validate(panels, layout));
  const int64_t n = static_cast<int64_t>(panels.size());
  const int64_t columns = std::min<int64_t>(layout.columns, n);
  const int64_t rows = (n + columns - 1) / columns;
  const int64_t width = columns * layout.panel_width, height = rows * layout.panel_height;
  if (width > kMaxImageSide || height > kMaxImageSide) {
    return absl::InvalidArgumentError(
        absl::StrCat("plot: image ", width, "x", height, " exceeds ", kMaxImageSide, " pixels"));
  }

  SurfacePtr surface(cairo_image_surface_create(CAIRO_FORMAT_RGB24, static_cast<int>(width),
                                                static_cast<int>(height)));
  if (cairo_surface_status(surface.get()) != CAIRO_STATUS_SUCCESS) {
    return absl::InternalError(
        absl::StrCat("plot: cannot create image surface: ",
                     cairo_status_to_string(cairo_surface_status(surface.get()))));
  }
  ContextPtr cr(cairo_create(surface.get()));
  cairo_set_source_rgb(cr.get(), 1, 1, 1);
  cairo_paint(cr.get());
  for (int64_t i = 0; i < n; ++i) {
    cairo_save(cr.get());
    cairo_translate(cr.get(), static_cast<double>((i % columns) * layout.panel_width),
                    static_cast<double>((i / columns) * layout.panel_height));
    DrawPanel(cr.get(), panels[i], layout.panel_width, layout.panel_height);
    cairo_restore(cr.get());
  }
  if (cairo_status(cr.get()) != CAIRO_STATUS_SUCCESS) {
    return absl::InternalError(
        absl::StrCat("plot: drawing failed: ", cairo_status_to_string(cairo_status(cr.get()))));
  }
  cairo_surface_flush(surface.get());
  const cairo_status_t written = cairo_surface_write_to_png(surface.get(), path.c_str());
  if (written != CAIRO_STATUS_SUCCESS) {
    return absl::UnavailableError(
        absl::StrCat("plot: cannot write PNG to '", path, "': ", cairo_status_to_string(written)));
  }
  return absl::OkStatus();
}

}  // namespace rvehub::plot
