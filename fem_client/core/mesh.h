// The finite-element mesh: node positions, elements, named node sets and
// named boundary edges (where pressures act), and a structured rectangle
// generator. Gauss points are numbered element by element, each element's
// in GaussPoints() order: that is the order the material sees them in.
#ifndef RVEHUB_FEM_CLIENT_CORE_MESH_H_
#define RVEHUB_FEM_CLIENT_CORE_MESH_H_

#include <Eigen/Dense>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "fem_client/core/element.h"

namespace rvehub::fem {

struct Element {
  ElementType type = ElementType::kQ4;
  std::vector<int> nodes;  // NodeCount(type) ids, counter-clockwise (see element.h)
};

// A boundary edge: its nodes start, end[, middle], with the body on the left
// going from start to end, so that the outward normal is the tangent turned
// clockwise.
struct Edge {
  std::vector<int> nodes;  // 2 (Q4) or 3 (Q8)
};

struct Mesh {
  std::vector<Eigen::Vector2d> nodes;  // m
  std::vector<Element> elements;
  std::map<std::string, std::vector<int>> node_sets;
  std::map<std::string, std::vector<Edge>> edge_sets;
};

// Checks what the solver relies on: every element has NodeCount(type) node
// ids in range, every node belongs to an element, node sets and edges name
// nodes in range, an edge has 2 or 3 nodes, and every element has det J > 0
// at each Gauss point. InvalidArgument naming the first offence.
absl::Status ValidateMesh(const Mesh& mesh);

struct RectangleSpec {
  double width = 1.0;   // m
  double height = 1.0;  // m
  int nx = 1;           // elements along x
  int ny = 1;           // elements along y
  ElementType type = ElementType::kQ4;
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();  // lower-left corner, m
};

// A width × height rectangle of nx × ny elements. Nodes go row by row from
// the bottom, left to right (Q8: the rows through element centres hold only
// the vertical edges' midsides). Node sets "left", "right", "bottom", "top"
// (sorted along the face, corners in both faces) and edge sets of the same
// names. InvalidArgument for sizes that are not positive and finite, or
// nx, ny outside [1, 10000] or nx·ny over 1e6.
absl::StatusOr<Mesh> StructuredRectangle(const RectangleSpec& spec);

// The nodes of element e at the positions `x` (one per mesh node).
ElementCoordinates ElementPositions(const Mesh& mesh, int element,
                                    std::span<const Eigen::Vector2d> x);

int CountGaussPoints(const Mesh& mesh);
// The first Gauss point of each element, and the total at the end
// (size elements + 1).
std::vector<int> GaussPointOffsets(const Mesh& mesh);
// Gauss-point positions at the node positions x (m).
std::vector<Eigen::Vector2d> GaussPointPositions(const Mesh& mesh,
                                                 std::span<const Eigen::Vector2d> x);

// The element and its local Gauss point of a global Gauss point, for
// messages: "Gauss point 7 (element 1, point 3 at (0.25, 0.75) m)".
std::string DescribeGaussPoint(const Mesh& mesh, int point);

}  // namespace rvehub::fem

#endif  // RVEHUB_FEM_CLIENT_CORE_MESH_H_
