#include "toolkit/plot.h"

#include <cairo.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "gtest/gtest.h"

namespace rvehub::plot {
namespace {

bool Contains(absl::string_view text, absl::string_view part) {
  return text.find(part) != absl::string_view::npos;
}

// A stress-strain-like curve and a volumetric curve, with a legend in panel 1.
std::vector<Panel> TwoPanels() {
  Series loose{"loose", {}, {}}, dense{"dense", {}, {}}, vol{"vol", {}, {}};
  for (int i = 0; i <= 50; ++i) {
    const double e = 0.002 * i;
    loose.x.push_back(e);
    loose.y.push_back(1e5 * (1 + 1.5 * (1 - std::exp(-60 * e))));
    dense.x.push_back(e);
    dense.y.push_back(1e5 * (1 + 2.5 * e / (0.01 + e)));
    vol.x.push_back(e);
    vol.y.push_back(-0.5 * e + 8 * e * e);
  }
  return {{"Deviatoric stress", "axial strain", "q [Pa]", {loose, dense}},
          {"Volumetric strain", "axial strain", "eps_v", {vol}}};
}

std::string ReadPrefix(const std::string& path, size_t n) {
  std::ifstream in(path, std::ios::binary);
  std::string bytes(n, '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(n));
  bytes.resize(static_cast<size_t>(in.gcount()));
  return bytes;
}

struct PngInfo {
  int width = 0, height = 0;
  int64_t non_white = 0, coloured = 0;  // coloured: r, g, b not all equal.
};

PngInfo ReadPng(const std::string& path) {
  PngInfo info;
  cairo_surface_t* s = cairo_image_surface_create_from_png(path.c_str());
  EXPECT_EQ(cairo_surface_status(s), CAIRO_STATUS_SUCCESS) << path;
  if (cairo_surface_status(s) == CAIRO_STATUS_SUCCESS) {
    info.width = cairo_image_surface_get_width(s);
    info.height = cairo_image_surface_get_height(s);
    const unsigned char* data = cairo_image_surface_get_data(s);
    const int stride = cairo_image_surface_get_stride(s);
    for (int y = 0; y < info.height; ++y) {
      const auto* row = reinterpret_cast<const uint32_t*>(data + static_cast<int64_t>(y) * stride);
      for (int x = 0; x < info.width; ++x) {
        const uint32_t r = (row[x] >> 16) & 0xff, g = (row[x] >> 8) & 0xff, b = row[x] & 0xff;
        if ((row[x] & 0xffffff) != 0xffffff) ++info.non_white;
        if (r != g || g != b) ++info.coloured;
      }
    }
  }
  cairo_surface_destroy(s);
  return info;
}

TEST(PlotTest, WritesTwoPanelPngWithLayoutSize) {
  const std::string path = ::testing::TempDir() + "/plot_test_two_panels.png";
  std::remove(path.c_str());
  const Layout layout{.columns = 2, .panel_width = 400, .panel_height = 300};
  ASSERT_TRUE(WritePng(path, TwoPanels(), layout).ok());

  EXPECT_EQ(ReadPrefix(path, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  const PngInfo info = ReadPng(path);
  EXPECT_EQ(info.width, 2 * 400);
  EXPECT_EQ(info.height, 300);
  EXPECT_GT(info.non_white, 2000);  // Axes, text and lines were drawn.
  EXPECT_GT(info.coloured, 200);    // The series lines are in colour.
}

TEST(PlotTest, GridWrapsIntoRowsAndNarrowsToPanelCount) {
  const std::string path = ::testing::TempDir() + "/plot_test_grid.png";
  std::vector<Panel> three = TwoPanels();
  three.push_back(three[0]);
  ASSERT_TRUE(WritePng(path, three).ok());
  PngInfo info = ReadPng(path);
  EXPECT_EQ(info.width, 2 * Layout{}.panel_width);
  EXPECT_EQ(info.height, 2 * Layout{}.panel_height);

  ASSERT_TRUE(WritePng(path, {TwoPanels()[1]}, Layout{.columns = 3}).ok());
  info = ReadPng(path);
  EXPECT_EQ(info.width, Layout{}.panel_width);
  EXPECT_EQ(info.height, Layout{}.panel_height);
}

TEST(PlotTest, HandlesDegenerateRanges) {
  const std::string path = ::testing::TempDir() + "/plot_test_degenerate.png";
  const std::vector<Panel> panels = {
      {"constant",
       "x",
       "y",
       {{"flat", {0, 1, 2}, {5, 5, 5}}, {"same", {1, 1}, {3, 3}}, {"empty", {}, {}}}},
      {"empty", "x", "y", {{"none", {}, {}}}},
      {"no series", "x", "y", {}},
      {"single point and zeros",
       "x",
       "y",
       {{"dot", {0.5e-300}, {0.5}}, {"tiny", {1e-300, 2e-300}, {-1e5, -1e5}}}},
  };
  ASSERT_TRUE(WritePng(path, panels).ok());
  const PngInfo info = ReadPng(path);
  EXPECT_EQ(info.width, 2 * Layout{}.panel_width);
  EXPECT_EQ(info.height, 2 * Layout{}.panel_height);
  EXPECT_GT(info.coloured, 0);
}

TEST(PlotTest, RejectsNoPanels) {
  const absl::Status status = WritePng(::testing::TempDir() + "/plot_test_none.png", {});
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
}

TEST(PlotTest, RejectsMismatchedSizes) {
  std::vector<Panel> panels = TwoPanels();
  panels[1].series[0].y.pop_back();
  const absl::Status status = WritePng(::testing::TempDir() + "/plot_test_bad.png", panels);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
  EXPECT_TRUE(Contains(status.message(), "'vol'")) << status;
}

TEST(PlotTest, RejectsNonFiniteValues) {
  for (double bad :
       {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    std::vector<Panel> panels = TwoPanels();
    panels[0].series[1].y[7] = bad;
    const absl::Status status = WritePng(::testing::TempDir() + "/plot_test_nan.png", panels);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
    EXPECT_TRUE(Contains(status.message(), "'dense'")) << status;
  }
  std::vector<Panel> panels = TwoPanels();
  panels[1].series[0].x[0] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(WritePng(::testing::TempDir() + "/plot_test_nan.png", panels).code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(PlotTest, RejectsBadLayout) {
  EXPECT_EQ(
      WritePng(::testing::TempDir() + "/plot_test_layout.png", TwoPanels(), Layout{.columns = 0})
          .code(),
      absl::StatusCode::kInvalidArgument);
}

TEST(PlotTest, ReportsUnwritablePath) {
  const std::string path = "/nonexistent_dir/x.png";
  const absl::Status status = WritePng(path, TwoPanels());
  EXPECT_EQ(status.code(), absl::StatusCode::kUnavailable) << status;
  EXPECT_TRUE(Contains(status.message(), path)) << status;
}

}  // namespace
}  // namespace rvehub::plot
