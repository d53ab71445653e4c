#include "fem_client/core/mesh.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace rvehub::fem {

absl::Status ValidateMesh(const Mesh& mesh) {
  const int n = static_cast<int>(mesh.nodes.size());
  const auto in_range = [n](int id) { return id >= 0 && id < n; };
  for (int a = 0; a < n; ++a) {
    if (!mesh.nodes[a].allFinite()) {
      return absl::InvalidArgumentError(absl::StrCat("node ", a, " has a position not finite"));
    }
  }
  if (mesh.elements.empty()) return absl::InvalidArgumentError("the mesh has no elements");
  std::vector<bool> used(n, false);
  for (int e = 0; e < static_cast<int>(mesh.elements.size()); ++e) {
    const Element& element = mesh.elements[e];
    if (static_cast<int>(element.nodes.size()) != NodeCount(element.type)) {
      return absl::InvalidArgumentError(absl::StrCat("element ", e, " (", ElementName(element.type),
                                                     ") has ", element.nodes.size(), " nodes, not ",
                                                     NodeCount(element.type)));
    }
    for (int id : element.nodes) {
      if (!in_range(id)) {
        return absl::InvalidArgumentError(
            absl::StrCat("element ", e, " names node ", id, ", outside [0, ", n, ")"));
      }
      used[id] = true;
    }
    const ElementCoordinates x = ElementPositions(mesh, e, mesh.nodes);
    for (int p = 0; p < GaussPointCount(element.type); ++p) {
      if (absl::StatusOr<PointGeometry> g = EvaluatePoint(element.type, x, p, e); !g.ok()) {
        return absl::InvalidArgumentError(
            absl::StrCat(g.status().message(), " (an element's nodes go counter-clockwise)"));
      }
    }
  }
  for (int a = 0; a < n; ++a) {
    if (!used[a]) {
      return absl::InvalidArgumentError(
          absl::StrCat("node ", a, " belongs to no element (it would have no stiffness)"));
    }
  }
  for (const auto& [name, ids] : mesh.node_sets) {
    for (int id : ids) {
      if (!in_range(id)) {
        return absl::InvalidArgumentError(
            absl::StrCat("node set \"", name, "\" names node ", id, ", outside [0, ", n, ")"));
      }
    }
  }
  for (const auto& [name, edges] : mesh.edge_sets) {
    for (const Edge& edge : edges) {
      if (edge.nodes.size() != 2 && edge.nodes.size() != 3) {
        return absl::InvalidArgumentError(absl::StrCat("edge set \"", name, "\" has an edge of ",
                                                       edge.nodes.size(), " nodes, not 2 or 3"));
      }
      for (int id : edge.nodes) {
        if (!in_range(id)) {
          return absl::InvalidArgumentError(
              absl::StrCat("edge set \"", name, "\" names node ", id, ", outside [0, ", n, ")"));
        }
      }
    }
  }
  return absl::OkStatus();
}

absl::StatusOr<Mesh> StructuredRectangle(const RectangleSpec& spec) {
  if (!(spec.width > 0.0 && std::isfinite(spec.width) && spec.height > 0.0 &&
        std::isfinite(spec.height) && spec.origin.allFinite())) {
    return absl::InvalidArgumentError(absl::StrCat("rectangle: width ", spec.width, " m, height ",
                                                   spec.height, " m must be positive and finite"));
  }
  if (spec.nx < 1 || spec.ny < 1 || spec.nx > 10000 || spec.ny > 10000 ||
      spec.nx * spec.ny > 1000000) {
    return absl::InvalidArgumentError(
        absl::StrCat("rectangle: ", spec.nx, " × ", spec.ny,
                     " elements, each must be in [1, 10000] and their product at most 1e6"));
  }
  // Grid positions (i, j); Q8 and Q8R use a grid twice as fine without the
  // centres.
  const int m = spec.type == ElementType::kQ4 ? 1 : 2;
  const int gx = m * spec.nx + 1, gy = m * spec.ny + 1;
  const auto is_node = [m](int i, int j) { return m == 1 || i % 2 == 0 || j % 2 == 0; };
  Mesh mesh;
  std::vector<int> id(static_cast<std::size_t>(gx) * gy, -1);
  const auto at = [&](int i, int j) -> int& { return id[static_cast<std::size_t>(j) * gx + i]; };
  for (int j = 0; j < gy; ++j) {
    for (int i = 0; i < gx; ++i) {
      if (!is_node(i, j)) continue;
      at(i, j) = static_cast<int>(mesh.nodes.size());
      mesh.nodes.push_back(spec.origin +
                           Eigen::Vector2d(spec.width * i / (gx - 1), spec.height * j / (gy - 1)));
    }
  }
  // Local node a of an element at grid offset (corners, then midsides).
  constexpr int kOffset[8][2] = {{0, 0}, {2, 0}, {2, 2}, {0, 2}, {1, 0}, {2, 1}, {1, 2}, {0, 1}};
  const int count = NodeCount(spec.type);
  for (int ey = 0; ey < spec.ny; ++ey) {
    for (int ex = 0; ex < spec.nx; ++ex) {
      Element element{spec.type, {}};
      for (int a = 0; a < count; ++a) {
        element.nodes.push_back(at(m * ex + kOffset[a][0] * m / 2, m * ey + kOffset[a][1] * m / 2));
      }
      mesh.elements.push_back(std::move(element));
    }
  }
  for (int j = 0; j < gy; ++j) {
    if (is_node(0, j)) mesh.node_sets["left"].push_back(at(0, j));
    if (is_node(gx - 1, j)) mesh.node_sets["right"].push_back(at(gx - 1, j));
  }
  for (int i = 0; i < gx; ++i) {
    mesh.node_sets["bottom"].push_back(at(i, 0));
    mesh.node_sets["top"].push_back(at(i, gy - 1));
  }
  // Faces 0..3 of the elements along each side: bottom, right, top, left.
  const auto add_edge = [&](const char* name, int e, int face) {
    const Element& element = mesh.elements[e];
    Edge edge;
    for (int local : FaceNodes(element.type, face)) {
      if (local >= 0) edge.nodes.push_back(element.nodes[local]);
    }
    mesh.edge_sets[name].push_back(std::move(edge));
  };
  for (int ex = 0; ex < spec.nx; ++ex) {
    add_edge("bottom", ex, 0);
    add_edge("top", (spec.ny - 1) * spec.nx + ex, 2);
  }
  for (int ey = 0; ey < spec.ny; ++ey) {
    add_edge("right", ey * spec.nx + spec.nx - 1, 1);
    add_edge("left", ey * spec.nx, 3);
  }
  return mesh;
}

ElementCoordinates ElementPositions(const Mesh& mesh, int element,
                                    std::span<const Eigen::Vector2d> x) {
  const Element& e = mesh.elements[element];
  ElementCoordinates c(static_cast<int>(e.nodes.size()), 2);
  for (int a = 0; a < c.rows(); ++a) c.row(a) = x[e.nodes[a]].transpose();
  return c;
}

int CountGaussPoints(const Mesh& mesh) { return GaussPointOffsets(mesh).back(); }

std::vector<int> GaussPointOffsets(const Mesh& mesh) {
  std::vector<int> offsets = {0};
  for (const Element& e : mesh.elements)
    offsets.push_back(offsets.back() + GaussPointCount(e.type));
  return offsets;
}

std::vector<Eigen::Vector2d> GaussPointPositions(const Mesh& mesh,
                                                 std::span<const Eigen::Vector2d> x) {
  std::vector<Eigen::Vector2d> out;
  for (int e = 0; e < static_cast<int>(mesh.elements.size()); ++e) {
    const ElementType type = mesh.elements[e].type;
    const ElementCoordinates c = ElementPositions(mesh, e, x);
    for (const GaussPoint& gp : GaussPoints(type)) {
      out.push_back(c.transpose() * ShapeFunctions(type, gp.xi));
    }
  }
  return out;
}

std::string DescribeGaussPoint(const Mesh& mesh, int point) {
  const std::vector<int> offsets = GaussPointOffsets(mesh);
  for (int e = 0; e + 1 < static_cast<int>(offsets.size()); ++e) {
    if (point < offsets[e + 1] && point >= offsets[e]) {
      const ElementType type = mesh.elements[e].type;
      const int local = point - offsets[e];
      const Eigen::Vector2d x = ElementPositions(mesh, e, mesh.nodes).transpose() *
                                ShapeFunctions(type, GaussPoints(type)[local].xi);
      return absl::StrFormat("Gauss point %d (element %d, point %d at (%.6g, %.6g) m)", point, e,
                             local, x.x(), x.y());
    }
  }
  return absl::StrCat("Gauss point ", point, " (not in the mesh)");
}

}  // namespace rvehub::fem
