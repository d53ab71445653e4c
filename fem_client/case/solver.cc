// The case's "solver" section: the tangent and the Newton iterations of a
// load step (G&Z §2.2, §3.3.2).
#include <string>

#include "absl/status/status.h"
#include "fem_client/case/sections.h"

namespace rvehub::fem::case_internal {
namespace {

constexpr Table<TangentKind> kTangents = {{"contact", TangentKind::kContact},
                                          {"perturbation", TangentKind::kPerturbation},
                                          {"initial-elastic", TangentKind::kInitialElastic}};

absl::string_view TangentName(TangentKind kind) {
  switch (kind) {
    case TangentKind::kContact:
      break;
    case TangentKind::kPerturbation:
      return "perturbation";
    case TangentKind::kInitialElastic:
      return "initial-elastic";
  }
  return "contact";
}

constexpr Table<PredictorKind> kPredictors = {{"zero", PredictorKind::kZero},
                                              {"previous", PredictorKind::kPrevious}};

absl::string_view PredictorName(PredictorKind kind) {
  return kind == PredictorKind::kPrevious ? "previous" : "zero";
}

constexpr Table<UnconvergedKind> kUnconverged = {{"stop", UnconvergedKind::kStop},
                                                 {"accept", UnconvergedKind::kAccept}};

absl::string_view UnconvergedName(UnconvergedKind kind) {
  return kind == UnconvergedKind::kAccept ? "accept" : "stop";
}

bool Perturbation(const SolverSpec& s) { return s.tangent == TangentKind::kPerturbation; }

Fields<SolverSpec> SolverFields() {
  // ξ: a perturbing strain above 1 % is no derivative. E_d is a relative
  // norm: at 1 nothing would ever iterate. Each cutback halves the step:
  // 20 of them are a millionth of it.
  return {
      EnumField("tangent", &SolverSpec::tangent, Need::kOptional, "tangent", kTangents,
                &TangentName),
      Only(&Perturbation, "only for tangent \"perturbation\"",
           NumberField("perturbation", &SolverSpec::perturbation, Need::kOptional,
                       Range{0.0, 0.01, true, false})),
      EnumField("predictor", &SolverSpec::predictor, Need::kOptional, "predictor", kPredictors,
                &PredictorName),
      NumberField("tolerance", &SolverSpec::tolerance, Need::kOptional,
                  Range{0.0, 1.0, true, true}),
      NumberField("force_tolerance", &SolverSpec::force_tolerance, Need::kOptional,
                  Range{0.0, 1.0, false, true}),
      IntField("max_iterations", &SolverSpec::max_iterations, 1, 1000),
      IntField("max_cutbacks", &SolverSpec::max_cutbacks, 0, 20),
      EnumField("unconverged", &SolverSpec::unconverged, Need::kOptional, "unconverged",
                kUnconverged, &UnconvergedName),
      // D: 1e6 N over a 1 mm element is a double stress of 1e9 Pa·m per
      // unit strain gradient, far past any granular layer's.
      NumberField("second_gradient_N", &SolverSpec::second_gradient, Need::kOptional,
                  Range{0.0, 1e6, false, false}),
  };
}

}  // namespace

absl::Status ParseSolver(const Json& j, const std::string& ptr, SolverSpec* solver) {
  return ReadFields(j, ptr, SolverFields(), solver).status();
}

OrderedJson WriteSolver(const SolverSpec& solver) { return WriteFields(SolverFields(), solver); }

}  // namespace rvehub::fem::case_internal
