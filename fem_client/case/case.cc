// The case reader's driver: the document (parse, overrides), the top level
// and the sections in order (sections.h), the memory estimate; and the
// canonical writer.
#include "fem_client/case/case.h"

#include <filesystem>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "client_case/sections.h"
#include "fem_client/case/sections.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/common/text_file.h"
#include "toolkit/json_document.h"

namespace rvehub::fem {
namespace case_internal {
namespace {

using fields::GetList;

// A quasi-static load step has no duration to cap an increment at, and a
// Gauss point no volume apart from its RVE's.
constexpr client_case::RveKeys kRveKeys{.real_time = false, .max_void_ratio = false};

// The case in `doc`, a section at a time: each is read after those it
// refers to (the material after the templates, the loading after the
// boundaries, the output after the mesh and the loading).
absl::StatusOr<FemCase> ReadCase(const Json& doc, const std::string& base_dir) {
  ASSIGN_OR_RETURN(Object root, Object::Open(doc, "",
                                             {"name", "description", "expected_runtime_s", "mesh",
                                              "templates", "material", "rve", "boundaries",
                                              "loading", "solver", "output", "checks"}));
  FemCase c;
  RETURN_IF_ERROR(GetString(root, "name", Need::kOptional, false, &c.name));
  RETURN_IF_ERROR(GetString(root, "description", Need::kOptional, false, &c.description));
  RETURN_IF_ERROR(
      GetNumber(root, "expected_runtime_s", Need::kOptional, kNonNegative, &c.expected_runtime_s));

  const Json* mesh = root.Get("mesh");
  if (mesh == nullptr) return root.Missing("mesh");
  RETURN_IF_ERROR(ParseMesh(*mesh, root.At("mesh"), &c.mesh));

  RETURN_IF_ERROR(GetList(root, "templates", Need::kRequired, "template", &c.templates,
                          [&](const Json& j, const std::string& ptr, size_t, TemplateSpec* t) {
                            return client_case::ParseTemplate(j, ptr, base_dir, t);
                          }));

  const Json* material = root.Get("material");
  if (material == nullptr) return root.Missing("material");
  RETURN_IF_ERROR(ParseMaterial(*material, root.At("material"), c.templates, &c.material));

  if (const Json* rve = root.Get("rve")) {
    RETURN_IF_ERROR(client_case::ParseRve(*rve, root.At("rve"), kRveKeys, &c.rve));
  }

  RETURN_IF_ERROR(GetList(root, "boundaries", Need::kRequired, "boundary", &c.boundaries,
                          [&](const Json& j, const std::string& ptr, size_t, BoundarySpec* b) {
                            return ParseBoundary(j, ptr, c.mesh, b);
                          }));
  RETURN_IF_ERROR(CheckBoundaries(c.boundaries, root.At("boundaries")));

  const Json* loading = root.Get("loading");
  if (loading == nullptr) return root.Missing("loading");
  RETURN_IF_ERROR(
      ParseLoading(*loading, root.At("loading"), c.boundaries, root.At("boundaries"), &c.loading));

  if (const Json* solver = root.Get("solver")) {
    RETURN_IF_ERROR(ParseSolver(*solver, root.At("solver"), &c.solver));
  }
  if (c.solver.second_gradient > 0.0 && c.mesh.element != ElementKind::kQ8R) {
    return Bad("/solver/second_gradient_N",
               "the second gradient needs the mesh's element \"q8r\" (Q8 displacements, "
               "2 x 2 Gauss points), not \"",
               ElementName(c.mesh.element), "\"");
  }

  c.output.plot = DefaultPlot(c.loading);
  if (const Json* output = root.Get("output")) {
    RETURN_IF_ERROR(
        ParseOutput(*output, root.At("output"), c.mesh, c.loading, base_dir, &c.output));
  }

  if (const Json* checks = root.Get("checks")) {
    RETURN_IF_ERROR(client_case::ParseChecks(*checks, root.At("checks"), &c.checks));
  }

  // Refused here rather than as std::bad_alloc while the RVEs are created.
  if (const double bytes = EstimateRveBytes(c); bytes > kMaxFemCaseBytes) {
    return Bad("/mesh", absl::StrFormat("the case's RVEs need about %.1f GiB (%d Gauss points), "
                                        "more than the limit of %.0f GiB: use fewer elements, "
                                        "q4 elements or smaller packings",
                                        bytes / (1 << 30), GaussPointCount(c.mesh),
                                        kMaxFemCaseBytes / (1 << 30)));
  }
  return c;
}

OrderedJson WriteCase(const FemCase& c) {
  OrderedJson doc;
  doc["name"] = c.name;
  doc["description"] = c.description;
  doc["expected_runtime_s"] = c.expected_runtime_s;
  doc["mesh"] = WriteMesh(c.mesh);
  OrderedJson& templates = doc["templates"] = OrderedJson::array();
  for (const TemplateSpec& t : c.templates) templates.push_back(client_case::WriteTemplate(t));
  doc["material"] = WriteMaterial(c.material);
  doc["rve"] = client_case::WriteRve(c.rve, kRveKeys);
  OrderedJson& boundaries = doc["boundaries"] = OrderedJson::array();
  for (const BoundarySpec& b : c.boundaries) boundaries.push_back(WriteBoundary(b));
  doc["loading"] = WriteLoading(c.loading);
  doc["solver"] = WriteSolver(c.solver);
  doc["output"] = WriteOutput(c.output);
  doc["checks"] = client_case::WriteChecks(c.checks);
  return doc;
}

}  // namespace
}  // namespace case_internal

double EstimateRveBytes(const FemCase& c) {
  int discs = 400;
  for (const TemplateSpec& t : c.templates) {
    if (t.name == c.material.rve_template) discs = client_case::EstimatedDiscs(t);
  }
  return static_cast<double>(GaussPointCount(c.mesh)) * discs * client_case::kRveBytesPerDisc;
}

absl::StatusOr<FemCase> ParseFemCase(absl::string_view json_text, const std::string& base_dir,
                                     std::span<const CaseOverride> overrides) {
  ASSIGN_OR_RETURN(fields::Json doc, fields::ParseJson(json_text));
  RETURN_IF_ERROR(client_case::ApplyOverrides(overrides, doc));
  return case_internal::ReadCase(doc, base_dir);
}

absl::StatusOr<FemCase> LoadFemCase(const std::string& path,
                                    std::span<const CaseOverride> overrides) {
  ASSIGN_OR_RETURN(std::string text, ReadTextFile(path, "case file"));
  const std::filesystem::path file(path);
  const std::string dir = file.has_parent_path() ? file.parent_path().string() : ".";
  absl::StatusOr<FemCase> c = ParseFemCase(text, dir, overrides);
  if (!c.ok()) {
    return absl::Status(c.status().code(), absl::StrCat(path, ": ", c.status().message()));
  }
  if (c->name.empty()) c->name = file.stem().string();
  return c;
}

std::string ToJson(const FemCase& c) { return fields::FormatJson(case_internal::WriteCase(c)); }

}  // namespace rvehub::fem
