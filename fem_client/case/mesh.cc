// The case's "mesh" section: a structured rectangle of Q4, Q8 or Q8R elements.
#include <cstdint>
#include <string>

#include "absl/status/status.h"
#include "fem_client/case/sections.h"

namespace rvehub::fem {

int GaussPointsPerElement(ElementKind kind) { return kind == ElementKind::kQ8 ? 9 : 4; }

std::int64_t GaussPointCount(const MeshSpec& mesh) {
  return static_cast<std::int64_t>(mesh.nx) * mesh.ny * GaussPointsPerElement(mesh.element);
}

namespace case_internal {
namespace {

// G&Z's finest mesh is 12 × 20; 200 × 200 Q8 elements are 360 000 RVEs,
// days of DEM per load step on a small cluster.
constexpr int kMaxElementsPerSide = 200;
// A specimen of metres to a slope of kilometres.
constexpr Range kSide{0.0, 1e4, true, false};  // m

constexpr Table<ElementKind> kElements = {
    {"q4", ElementKind::kQ4}, {"q8", ElementKind::kQ8}, {"q8r", ElementKind::kQ8R}};

Fields<MeshSpec> MeshFields() {
  return {
      Vec2Field("origin", &MeshSpec::origin, Need::kOptional, kAny),
      Vec2Field("size", &MeshSpec::size, Need::kRequired, kSide),
      {"elements",
       [](const Object& o, MeshSpec* mesh) -> absl::Status {
         const Json* n = o.Get("elements");
         if (n == nullptr) return o.Missing("elements");
         if (!n->is_array() || n->size() != 2) {
           return Bad(o.At("elements"), "must be an array of 2 integers [nx, ny], got ", Got(*n));
         }
         RETURN_IF_ERROR(
             ReadInt((*n)[0], Child(o.At("elements"), 0), 1, kMaxElementsPerSide, &mesh->nx));
         return ReadInt((*n)[1], Child(o.At("elements"), 1), 1, kMaxElementsPerSide, &mesh->ny);
       },
       [](const MeshSpec& mesh, OrderedJson& j) {
         j["elements"] = OrderedJson::array({mesh.nx, mesh.ny});
       }},
      EnumField("element", &MeshSpec::element, Need::kOptional, "element", kElements, &ElementName),
  };
}

}  // namespace

absl::string_view ElementName(ElementKind kind) {
  switch (kind) {
    case ElementKind::kQ4:
      return "q4";
    case ElementKind::kQ8:
      return "q8";
    case ElementKind::kQ8R:
      break;
  }
  return "q8r";
}

int NodesAlongFace(const MeshSpec& mesh, Face face) {
  const int elements = face == Face::kLeft || face == Face::kRight ? mesh.ny : mesh.nx;
  return (mesh.element == ElementKind::kQ4 ? elements : 2 * elements) + 1;
}

absl::Status ParseMesh(const Json& j, const std::string& ptr, MeshSpec* mesh) {
  return ReadFields(j, ptr, MeshFields(), mesh).status();
}

OrderedJson WriteMesh(const MeshSpec& mesh) { return WriteFields(MeshFields(), mesh); }

}  // namespace case_internal
}  // namespace rvehub::fem
