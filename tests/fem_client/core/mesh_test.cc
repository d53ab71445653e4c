#include "fem_client/core/mesh.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <string>

#include "absl/status/status.h"
#include "absl/strings/match.h"

namespace rvehub::fem {
namespace {

RectangleSpec Spec(ElementType type) {
  RectangleSpec spec;
  spec.width = 2.0;
  spec.height = 3.0;
  spec.nx = 2;
  spec.ny = 3;
  spec.type = type;
  spec.origin = Eigen::Vector2d(-1.0, 0.5);
  return spec;
}

double Area(const Mesh& mesh) {
  double area = 0.0;
  for (int e = 0; e < static_cast<int>(mesh.elements.size()); ++e) {
    const ElementType type = mesh.elements[e].type;
    for (int p = 0; p < GaussPointCount(type); ++p) {
      area += EvaluatePoint(type, ElementPositions(mesh, e, mesh.nodes), p, e)->volume;
    }
  }
  return area;
}

TEST(MeshTest, AStructuredQ4RectangleHasItsNodesElementsAndSets) {
  const absl::StatusOr<Mesh> mesh = StructuredRectangle(Spec(ElementType::kQ4));
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(mesh->nodes.size(), 3u * 4u);
  EXPECT_EQ(mesh->elements.size(), 6u);
  EXPECT_TRUE(ValidateMesh(*mesh).ok()) << ValidateMesh(*mesh);
  EXPECT_NEAR(Area(*mesh), 6.0, 1e-12);
  // Row by row from the bottom: node i + 3 j at (−1 + i, 0.5 + j).
  EXPECT_EQ(mesh->nodes[7], Eigen::Vector2d(0.0, 2.5));
  EXPECT_EQ(mesh->elements[0].nodes, (std::vector<int>{0, 1, 4, 3}));
  EXPECT_EQ(mesh->node_sets.at("left"), (std::vector<int>{0, 3, 6, 9}));
  EXPECT_EQ(mesh->node_sets.at("right"), (std::vector<int>{2, 5, 8, 11}));
  EXPECT_EQ(mesh->node_sets.at("bottom"), (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(mesh->node_sets.at("top"), (std::vector<int>{9, 10, 11}));
  EXPECT_EQ(mesh->edge_sets.at("left").size(), 3u);
  EXPECT_EQ(mesh->edge_sets.at("top").size(), 2u);
}

TEST(MeshTest, AStructuredQ8RectangleLeavesOutTheCentres) {
  const absl::StatusOr<Mesh> mesh = StructuredRectangle(Spec(ElementType::kQ8));
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  // (2nx + 1)(2ny + 1) − nx·ny.
  EXPECT_EQ(mesh->nodes.size(), 5u * 7u - 6u);
  EXPECT_TRUE(ValidateMesh(*mesh).ok()) << ValidateMesh(*mesh);
  EXPECT_NEAR(Area(*mesh), 6.0, 1e-12);
  // Element 0: corners 0, 2, 10, 8 (rows of 5, 3, 5 nodes), midsides 1, 6, 9, 5.
  EXPECT_EQ(mesh->elements[0].nodes, (std::vector<int>{0, 2, 10, 8, 1, 6, 9, 5}));
  EXPECT_EQ(mesh->node_sets.at("left").size(), 7u);
  EXPECT_EQ(mesh->node_sets.at("bottom").size(), 5u);
  for (const Edge& edge : mesh->edge_sets.at("right")) EXPECT_EQ(edge.nodes.size(), 3u);
  // Every midside lies halfway between its corners.
  for (const Element& e : mesh->elements) {
    for (int a = 0; a < 4; ++a) {
      const Eigen::Vector2d mid =
          0.5 * (mesh->nodes[e.nodes[a]] + mesh->nodes[e.nodes[(a + 1) % 4]]);
      EXPECT_LT((mesh->nodes[e.nodes[4 + a]] - mid).norm(), 1e-15);
    }
  }
}

// Each face's edges run with the body on their left: the tangent turned
// clockwise points out of the rectangle, and the edges cover the face.
TEST(MeshTest, BoundaryEdgesRunWithTheBodyOnTheirLeft) {
  for (ElementType type : {ElementType::kQ4, ElementType::kQ8}) {
    const Mesh mesh = *StructuredRectangle(Spec(type));
    const std::pair<std::string, Eigen::Vector2d> faces[] = {
        {"left", {-1, 0}}, {"right", {1, 0}}, {"bottom", {0, -1}}, {"top", {0, 1}}};
    for (const auto& [name, outward] : faces) {
      double length = 0.0;
      for (const Edge& edge : mesh.edge_sets.at(name)) {
        const Eigen::Vector2d t = mesh.nodes[edge.nodes[1]] - mesh.nodes[edge.nodes[0]];
        EXPECT_LT((Eigen::Vector2d(t.y(), -t.x()).normalized() - outward).norm(), 1e-15) << name;
        length += t.norm();
        for (int id : edge.nodes) {
          const std::vector<int>& set = mesh.node_sets.at(name);
          EXPECT_NE(std::find(set.begin(), set.end(), id), set.end()) << name << " " << id;
        }
      }
      EXPECT_NEAR(length, name == "left" || name == "right" ? 3.0 : 2.0, 1e-12) << name;
    }
  }
}

TEST(MeshTest, GaussPointsAreNumberedElementByElement) {
  RectangleSpec spec;
  spec.nx = 2;
  const Mesh mesh = *StructuredRectangle(spec);
  EXPECT_EQ(CountGaussPoints(mesh), 8);
  EXPECT_EQ(GaussPointOffsets(mesh), (std::vector<int>{0, 4, 8}));
  const std::vector<Eigen::Vector2d> x = GaussPointPositions(mesh, mesh.nodes);
  ASSERT_EQ(x.size(), 8u);
  const double g = 0.5 / std::sqrt(3.0);
  // Element 1 spans [0.5, 1] × [0, 1]; its points go ξ fastest.
  EXPECT_LT((x[5] - Eigen::Vector2d(0.75 + 0.5 * g, 0.5 - g)).norm(), 1e-15);
  EXPECT_LT((x[6] - Eigen::Vector2d(0.75 - 0.5 * g, 0.5 + g)).norm(), 1e-15);
  EXPECT_TRUE(absl::StrContains(DescribeGaussPoint(mesh, 6), "Gauss point 6 (element 1, point 2"));
}

TEST(MeshTest, BadRectanglesAreRefused) {
  RectangleSpec spec;
  spec.width = -1.0;
  EXPECT_EQ(StructuredRectangle(spec).status().code(), absl::StatusCode::kInvalidArgument);
  spec.width = 1.0;
  spec.ny = 0;
  EXPECT_EQ(StructuredRectangle(spec).status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(MeshTest, ValidateMeshNamesTheFirstOffence) {
  const Mesh good = *StructuredRectangle(Spec(ElementType::kQ4));
  const auto expect = [](const Mesh& mesh, const std::string& says) {
    const absl::Status s = ValidateMesh(mesh);
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << says;
    EXPECT_TRUE(absl::StrContains(s.message(), says)) << s;
  };
  Mesh m = good;
  m.elements[2].nodes[1] = 99;
  expect(m, "element 2 names node 99");
  m = good;
  m.elements[1].nodes.pop_back();
  expect(m, "element 1 (Q4) has 3 nodes, not 4");
  m = good;
  m.nodes.push_back({5, 5});
  expect(m, "node 12 belongs to no element");
  m = good;
  std::swap(m.elements[4].nodes[1], m.elements[4].nodes[3]);  // clockwise
  expect(m, "element 4 (Q4) is inverted at Gauss point 0");
  m = good;
  m.node_sets["top"].push_back(-1);
  expect(m, "node set \"top\" names node -1");
  m = good;
  m.edge_sets["left"][0].nodes = {1};
  expect(m, "edge set \"left\" has an edge of 1 nodes");
}

}  // namespace
}  // namespace rvehub::fem
