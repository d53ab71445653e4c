// The case's "material" section: the template every Gauss point's RVE is
// created from, and the stress it starts at.
#include <algorithm>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_join.h"
#include "fem_client/case/sections.h"

namespace rvehub::fem::case_internal {
namespace {

constexpr Table<InitialStressKind> kInitialStresses = {{"template", InitialStressKind::kTemplate},
                                                       {"isotropic", InitialStressKind::kIsotropic},
                                                       {"k0", InitialStressKind::kK0}};

absl::string_view InitialStressName(InitialStressKind kind) {
  switch (kind) {
    case InitialStressKind::kTemplate:
      break;
    case InitialStressKind::kIsotropic:
      return "isotropic";
    case InitialStressKind::kK0:
      return "k0";
  }
  return "template";
}

bool Isotropic(const MaterialSpec& m) { return m.initial_stress == InitialStressKind::kIsotropic; }
bool K0(const MaterialSpec& m) { return m.initial_stress == InitialStressKind::kK0; }

// K0 of soils at rest lies near 0.4–0.6 and passive states below about 6:
// beyond 10 a packing would fail before it starts.
constexpr Range kK0Range{0.0, 10.0, true, false};

// The keys of "initial_stress".
Fields<MaterialSpec> InitialStressFields() {
  return {
      EnumField("kind", &MaterialSpec::initial_stress, Need::kRequired, "initial stress kind",
                kInitialStresses, &InitialStressName),
      Only(&Isotropic, "only for kind \"isotropic\"",
           NumberField("pressure", &MaterialSpec::pressure, Need::kRequired, kPackingStress)),
      Only(&K0, "only for kind \"k0\"",
           NumberField("vertical", &MaterialSpec::vertical, Need::kRequired, kPackingStress)),
      Only(&K0, "only for kind \"k0\"",
           NumberField("k0", &MaterialSpec::k0, Need::kOptional, kK0Range)),
  };
}

// `templates`: the case's, for the template's check (null when only writing).
Fields<MaterialSpec> MaterialFields(const std::vector<TemplateSpec>* templates) {
  return {
      {"template",
       [templates](const Object& o, MaterialSpec* m) -> absl::Status {
         RETURN_IF_ERROR(GetString(o, "template", Need::kRequired, true, &m->rve_template));
         if (std::none_of(templates->begin(), templates->end(),
                          [&](const TemplateSpec& t) { return t.name == m->rve_template; })) {
           return Bad(o.At("template"), "no template named ", Quote(m->rve_template),
                      " (templates: ", absl::StrJoin(NamesOf(*templates), ", "), ")");
         }
         return absl::OkStatus();
       },
       [](const MaterialSpec& m, OrderedJson& j) { j["template"] = m.rve_template; }},
      {"initial_stress",
       [](const Object& o, MaterialSpec* m) -> absl::Status {
         const Json* v = o.Get("initial_stress");
         return v == nullptr
                    ? absl::OkStatus()
                    : ReadFields(*v, o.At("initial_stress"), InitialStressFields(), m).status();
       },
       [](const MaterialSpec& m, OrderedJson& j) {
         j["initial_stress"] = WriteFields(InitialStressFields(), m);
       }},
  };
}

}  // namespace

absl::Status ParseMaterial(const Json& j, const std::string& ptr,
                           const std::vector<TemplateSpec>& templates, MaterialSpec* material) {
  return ReadFields(j, ptr, MaterialFields(&templates), material).status();
}

OrderedJson WriteMaterial(const MaterialSpec& material) {
  return WriteFields(MaterialFields(nullptr), material);
}

}  // namespace rvehub::fem::case_internal
