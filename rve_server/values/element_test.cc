#include "rve_server/values/element_test.h"

#include <string>

#include "absl/strings/str_cat.h"

namespace rvehub::dem {
namespace {

struct NamedKind {
  const char* name;
  ElementTestKind kind;
};
constexpr NamedKind kKinds[] = {
    {"drained-biaxial", ElementTestKind::kDrainedBiaxial},
    {"isotropic", ElementTestKind::kIsotropic},
    {"oedometer", ElementTestKind::kOedometer},
    {"undrained-simple-shear", ElementTestKind::kUndrainedSimpleShear},
    {"cyclic-simple-shear", ElementTestKind::kCyclicSimpleShear},
};

}  // namespace

bool HasLoadingAxis(ElementTestKind kind) {
  return kind == ElementTestKind::kDrainedBiaxial || kind == ElementTestKind::kOedometer;
}

absl::StatusOr<ElementTestKind> ParseElementTestKind(absl::string_view name) {
  std::string known;
  for (const NamedKind& k : kKinds) {
    if (name == k.name) return k.kind;
    absl::StrAppend(&known, known.empty() ? "" : ", ", k.name);
  }
  return absl::InvalidArgumentError(
      absl::StrCat("unknown element test '", name, "'; known: ", known));
}

}  // namespace rvehub::dem
