// The case's "loading" section: the load steps that drive the platen or the
// shear platen.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "fem_client/case/sections.h"

namespace rvehub::fem::case_internal {
namespace {

constexpr Table<LoadingKind> kKinds = {{"compression", LoadingKind::kCompression},
                                       {"shear", LoadingKind::kShear},
                                       {"cyclic_shear", LoadingKind::kCyclicShear}};

// Every load step is a Newton solve over all the RVEs: a million is weeks.
constexpr std::int64_t kMaxSteps = 1000000;
// Nominal strains beyond these leave a small-strain mesh badly distorted.
constexpr Range kEndAxialStrain{0.0, 0.5, true, false};
constexpr Range kEndShearStrain{0.0, 1.0, true, false};
// One load step of more than 5 % strain is a jump, not an increment.
constexpr Range kStrainStep{0.0, 0.05, true, false};
constexpr Range kStrainAmplitude{0.0, 0.2, true, false};
constexpr int kMaxCycles = 1000;

bool Compression(const LoadingSpec& l) { return l.kind == LoadingKind::kCompression; }
bool Monotonic(const LoadingSpec& l) { return l.kind != LoadingKind::kCyclicShear; }
bool Cyclic(const LoadingSpec& l) { return l.kind == LoadingKind::kCyclicShear; }
bool MonotonicShear(const LoadingSpec& l) { return l.kind == LoadingKind::kShear; }
// Where end_shear_strain applies: a monotonic shear's end, or where a
// stress-controlled cyclic shear stops.
bool EndsInShear(const LoadingSpec& l) {
  return l.kind == LoadingKind::kShear ||
         (l.kind == LoadingKind::kCyclicShear && l.control == CyclicControl::kStress);
}

// The step key of a monotonic loading: its strain per step.
absl::string_view StepKey(const LoadingSpec& l) {
  return Compression(l) ? "axial_strain_step" : "shear_strain_step";
}

constexpr absl::string_view kOnlyCyclic = "only for kind \"cyclic_shear\"";

Fields<LoadingSpec> LoadingFields() {
  return {
      EnumField("kind", &LoadingSpec::kind, Need::kRequired, "loading kind", kKinds,
                &LoadingKindName),
      // Cyclic: the amplitude (its key says the control), cycles, steps per cycle.
      {"strain_amplitude",
       [](const Object& o, LoadingSpec* l) -> absl::Status {
         if (!Cyclic(*l)) {
           RETURN_IF_ERROR(Forbid(o, "strain_amplitude", kOnlyCyclic));
           return Forbid(o, "stress_amplitude", kOnlyCyclic);
         }
         if (o.Has("strain_amplitude") == o.Has("stress_amplitude")) {
           return Bad(o.ptr(),
                      "give exactly one of \"strain_amplitude\" (γ, strain control) or "
                      "\"stress_amplitude\" (|τ| in Pa, stress control)");
         }
         if (o.Has("strain_amplitude")) {
           l->control = CyclicControl::kStrain;
           return GetNumber(o, "strain_amplitude", Need::kRequired, kStrainAmplitude,
                            &l->amplitude);
         }
         l->control = CyclicControl::kStress;
         return GetNumber(o, "stress_amplitude", Need::kRequired, kPackingStress, &l->amplitude);
       },
       [](const LoadingSpec& l, OrderedJson& j) {
         if (Cyclic(l) && l.control == CyclicControl::kStrain) j["strain_amplitude"] = l.amplitude;
       }},
      // Read with strain_amplitude; written here, in the table's order.
      {"stress_amplitude", [](const Object&, LoadingSpec*) { return absl::OkStatus(); },
       [](const LoadingSpec& l, OrderedJson& j) {
         if (Cyclic(l) && l.control == CyclicControl::kStress) j["stress_amplitude"] = l.amplitude;
       }},
      Only(&Cyclic, kOnlyCyclic,
           {"cycles",
            [](const Object& o, LoadingSpec* l) -> absl::Status {
              const Json* v = o.Get("cycles");
              if (v == nullptr) return o.Missing("cycles");
              return ReadInt(*v, o.At("cycles"), 1, kMaxCycles, &l->cycles);
            },
            [](const LoadingSpec& l, OrderedJson& j) { j["cycles"] = l.cycles; }}),
      Only(
          &Cyclic, kOnlyCyclic,
          {"steps_per_cycle",
           [](const Object& o, LoadingSpec* l) -> absl::Status {
             const Json* v = o.Get("steps_per_cycle");
             if (v == nullptr) return o.Missing("steps_per_cycle");
             const std::string at = o.At("steps_per_cycle");
             RETURN_IF_ERROR(ReadInteger(*v, at, 4, kMaxSteps, &l->steps_per_cycle));
             // Four equal quarters: every peak of the amplitude is a step's end.
             if (l->steps_per_cycle % 4 != 0) {
               return Bad(at, "must be a multiple of 4 (a cycle's four equal quarters), got ",
                          l->steps_per_cycle);
             }
             if (l->steps_per_cycle * l->cycles > kMaxSteps) {
               return Bad(at, "cycles × steps_per_cycle must be at most ", kMaxSteps, ", got ",
                          l->cycles, " × ", l->steps_per_cycle);
             }
             return absl::OkStatus();
           },
           [](const LoadingSpec& l, OrderedJson& j) { j["steps_per_cycle"] = l.steps_per_cycle; }}),
      // The end of a monotonic loading (or where a stress-controlled cycle stops).
      Only(&Compression, "only for kind \"compression\"",
           NumberField("end_axial_strain", &LoadingSpec::end_strain, Need::kRequired,
                       kEndAxialStrain)),
      {"end_shear_strain",
       [](const Object& o, LoadingSpec* l) -> absl::Status {
         if (!EndsInShear(*l)) {
           return Forbid(o, "end_shear_strain",
                         Cyclic(*l) ? "only with a \"stress_amplitude\" (where a stress-controlled "
                                      "cycle stops; a strain-controlled one stays within its "
                                      "amplitude)"
                                    : "only for kinds \"shear\" and \"cyclic_shear\"");
         }
         return GetNumber(o, "end_shear_strain",
                          MonotonicShear(*l) ? Need::kRequired : Need::kOptional, kEndShearStrain,
                          &l->end_strain);
       },
       [](const LoadingSpec& l, OrderedJson& j) {
         if (EndsInShear(l) && std::isfinite(l.end_strain)) j["end_shear_strain"] = l.end_strain;
       }},
      // The step keys are read with "steps" (below); here only refused where
      // they do not apply.
      Only(&Compression, "only for kind \"compression\"",
           {"axial_strain_step", [](const Object&, LoadingSpec*) { return absl::OkStatus(); },
            [](const LoadingSpec&, OrderedJson&) {}}),
      Only(&MonotonicShear, "only for kind \"shear\"",
           {"shear_strain_step", [](const Object&, LoadingSpec*) { return absl::OkStatus(); },
            [](const LoadingSpec&, OrderedJson&) {}}),
      // The monotonic loadings' steps: a count, or a strain per step that
      // gives the count (rounded up, so no step is larger than asked).
      Only(&Monotonic,
           "only for kinds \"compression\" and \"shear\" (a cyclic shear counts "
           "steps_per_cycle)",
           {"steps",
            [](const Object& o, LoadingSpec* l) -> absl::Status {
              const absl::string_view step_key = StepKey(*l);
              if (o.Has("steps") == o.Has(step_key)) {
                return Bad(o.ptr(), "give exactly one of \"steps\" (load steps to the end) or ",
                           Quote(step_key), " (strain per step)");
              }
              if (o.Has("steps")) {
                return ReadInteger(*o.Get("steps"), o.At("steps"), 1, kMaxSteps, &l->steps);
              }
              double step = 0.0;
              RETURN_IF_ERROR(GetNumber(o, step_key, Need::kRequired, kStrainStep, &step));
              // 0.1/1e-3 is 100.00000000000001 in doubles: not a 101st step.
              const double steps = std::ceil(l->end_strain / step * (1.0 - 1e-9));
              if (steps > static_cast<double>(kMaxSteps)) {
                return Bad(o.At(step_key), "gives ", Num(steps), " steps to the end strain ",
                           Num(l->end_strain), ", more than ", kMaxSteps);
              }
              l->steps = std::max<std::int64_t>(1, static_cast<std::int64_t>(steps));
              return absl::OkStatus();
            },
            [](const LoadingSpec& l, OrderedJson& j) { j["steps"] = l.steps; }}),
  };
}

}  // namespace

absl::string_view LoadingKindName(LoadingKind kind) {
  switch (kind) {
    case LoadingKind::kCompression:
      break;
    case LoadingKind::kShear:
      return "shear";
    case LoadingKind::kCyclicShear:
      return "cyclic_shear";
  }
  return "compression";
}

absl::Status ParseLoading(const Json& j, const std::string& ptr,
                          const std::vector<BoundarySpec>& boundaries,
                          const std::string& boundaries_ptr, LoadingSpec* loading) {
  ASSIGN_OR_RETURN(Object o, ReadFields(j, ptr, LoadingFields(), loading));
  // The loading drives the one driven boundary (CheckBoundaries found it).
  for (std::size_t i = 0; i < boundaries.size(); ++i) {
    const BoundaryKind kind = boundaries[i].kind;
    if (kind != BoundaryKind::kPlaten && kind != BoundaryKind::kShear) continue;
    const bool compression = loading->kind == LoadingKind::kCompression;
    if (compression != (kind == BoundaryKind::kPlaten)) {
      return Bad(o.At("kind"), Quote(LoadingKindName(loading->kind)), " drives ",
                 compression ? "a platen" : "the top's shear platen", ", and the case's driven ",
                 "boundary is ", BoundaryKindName(kind), " boundary ", Quote(boundaries[i].name),
                 " (", Child(boundaries_ptr, i), ")");
    }
  }
  return absl::OkStatus();
}

OrderedJson WriteLoading(const LoadingSpec& loading) {
  return WriteFields(LoadingFields(), loading);
}

}  // namespace rvehub::fem::case_internal
