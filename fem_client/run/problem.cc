#include "fem_client/run/problem.h"

#include <map>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "rve_server/common/status_macros.h"

namespace rvehub::fem {
namespace {

const char* AxisName(int dof) { return dof == 0 ? "x" : "y"; }

// The axis of a face's normal: x for left and right, y for bottom and top.
int NormalDof(Face face) { return face == Face::kLeft || face == Face::kRight ? 0 : 1; }

ElementType CoreElement(ElementKind kind) {
  switch (kind) {
    case ElementKind::kQ4:
      return ElementType::kQ4;
    case ElementKind::kQ8:
      return ElementType::kQ8;
    case ElementKind::kQ8R:
      break;
  }
  return ElementType::kQ8R;
}

TangentOperator CoreTangent(TangentKind kind) {
  switch (kind) {
    case TangentKind::kPerturbation:
      return TangentOperator::kPerturbation;
    case TangentKind::kInitialElastic:
      return TangentOperator::kInitialElastic;
    case TangentKind::kContact:
      break;
  }
  return TangentOperator::kContact;
}

// The prescribed dofs in the order given, each (node, dof) once: the first
// boundary to claim a dof keeps it.
class Prescriptions {
 public:
  explicit Prescriptions(const Mesh& mesh) : mesh_(mesh) {}

  // Prescribes `increment` (m per step at factor 1) on (node, dof) unless a
  // boundary before did; a support's hold of a dof the driven face moves is
  // noted (once per boundary).
  void Add(int node, int dof, double increment, const std::string& boundary) {
    const auto [it, inserted] = claimed_.emplace(std::pair{node, dof}, increment);
    if (inserted) {
      order_.push_back({node, dof, increment});
      return;
    }
    if (it->second != increment && !noted_.contains(boundary)) {
      noted_.insert({boundary, true});
      const Eigen::Vector2d& x = mesh_.nodes[node];
      notes_.push_back(absl::StrFormat(
          "note: boundary %s would hold node %d at (%.6g, %.6g) m along %s, which the driven "
          "face moves: the node moves with the driven face",
          boundary, node, x.x(), x.y(), AxisName(dof)));
    }
  }

  std::vector<Prescribed> TakePrescribed() { return std::move(order_); }
  std::vector<std::string> TakeNotes() { return std::move(notes_); }

 private:
  const Mesh& mesh_;
  std::map<std::pair<int, int>, double> claimed_;
  std::map<std::string, bool> noted_;
  std::vector<Prescribed> order_;
  std::vector<std::string> notes_;
};

// The load factor of every step (Step(factor)).
std::vector<double> LoadFactors(const LoadingSpec& loading) {
  if (loading.kind != LoadingKind::kCyclicShear) {
    return std::vector<double>(static_cast<std::size_t>(loading.steps), 1.0);
  }
  // 0 → +A → −A → 0 in four equal quarters: out, back twice, out again.
  std::vector<double> factors;
  const std::int64_t quarter = loading.steps_per_cycle / 4;
  for (int cycle = 0; cycle < loading.cycles; ++cycle) {
    for (std::int64_t k = 0; k < loading.steps_per_cycle; ++k) {
      const std::int64_t q = k / quarter;
      factors.push_back(q == 1 || q == 2 ? -1.0 : 1.0);
    }
  }
  return factors;
}

// The load of one step at factor 1: the axial strain (compression), the
// shear strain γ (shear, strain-controlled cycles), [-]; the shear stress τ
// (stress-controlled cycles), Pa.
double StepStrain(const LoadingSpec& loading) {
  if (loading.kind == LoadingKind::kCyclicShear) {
    return 4.0 * loading.amplitude / static_cast<double>(loading.steps_per_cycle);
  }
  return loading.end_strain / static_cast<double>(loading.steps);
}

}  // namespace

std::string FaceSetName(Face face) {
  switch (face) {
    case Face::kLeft:
      return "left";
    case Face::kRight:
      return "right";
    case Face::kBottom:
      return "bottom";
    case Face::kTop:
      break;
  }
  return "top";
}

Eigen::Vector2d OutwardNormal(Face face) {
  switch (face) {
    case Face::kLeft:
      return {-1.0, 0.0};
    case Face::kRight:
      return {1.0, 0.0};
    case Face::kBottom:
      return {0.0, -1.0};
    case Face::kTop:
      break;
  }
  return {0.0, 1.0};
}

Eigen::Vector2d FaceTangent(Face face) {
  return NormalDof(face) == 0 ? Eigen::Vector2d(0.0, 1.0) : Eigen::Vector2d(1.0, 0.0);
}

absl::StatusOr<Problem> BuildProblem(const FemCase& c) {
  Problem p;
  RectangleSpec rect;
  rect.origin = c.mesh.origin;
  rect.width = c.mesh.size.x();
  rect.height = c.mesh.size.y();
  rect.nx = c.mesh.nx;
  rect.ny = c.mesh.ny;
  rect.type = CoreElement(c.mesh.element);
  ASSIGN_OR_RETURN(p.mesh, StructuredRectangle(rect));
  const Mesh& mesh = p.mesh;

  const BoundarySpec* driven = nullptr;
  for (const BoundarySpec& b : c.boundaries) {
    if (b.kind == BoundaryKind::kPlaten || b.kind == BoundaryKind::kShear) driven = &b;
  }
  if (driven == nullptr) {
    return absl::InvalidArgumentError("/boundaries: no platen or shear platen drives the specimen");
  }
  p.driven = driven->face;
  p.shear = driven->kind == BoundaryKind::kShear;
  p.forced =
      c.loading.kind == LoadingKind::kCyclicShear && c.loading.control == CyclicControl::kStress;
  p.length_across = NormalDof(p.driven) == 1 ? c.mesh.size.y() : c.mesh.size.x();
  p.lateral = p.shear ? p.driven : (NormalDof(p.driven) == 1 ? Face::kRight : Face::kTop);
  p.factors = LoadFactors(c.loading);

  Prescriptions prescribed(mesh);
  const double strain = StepStrain(c.loading);  // [-] per step at factor 1
  {
    const std::vector<int>& nodes = mesh.node_sets.at(FaceSetName(p.driven));
    if (p.shear && p.forced) {
      // Stress control: the platen's horizontal force τ·W per step (W the
      // initial width), its nodes moving together; the height held.
      AddForcedPlaten(nodes, 0, strain * c.mesh.size.x(), p.boundary);
      for (int node : nodes) prescribed.Add(node, 1, 0.0, driven->name);
    } else if (p.shear) {
      // Towards +x by γ·H, the height held.
      for (int node : nodes) {
        prescribed.Add(node, 0, strain * p.length_across, driven->name);
        prescribed.Add(node, 1, 0.0, driven->name);
      }
    } else {
      const int normal = NormalDof(p.driven);
      const double increment = -strain * p.length_across * OutwardNormal(p.driven)[normal];  // m
      for (int node : nodes) {
        prescribed.Add(node, normal, increment, driven->name);
        if (driven->contact == Contact::kRough) prescribed.Add(node, 1 - normal, 0.0, driven->name);
      }
    }
  }
  bool periodic = false;
  for (const BoundarySpec& b : c.boundaries) {
    if (&b == driven) continue;
    const std::vector<int>& nodes = mesh.node_sets.at(FaceSetName(b.face));
    switch (b.kind) {
      case BoundaryKind::kFixed:
        for (int node : nodes) {
          for (int dof : {0, 1}) prescribed.Add(node, dof, 0.0, b.name);
        }
        break;
      case BoundaryKind::kRoller: {
        const int normal = NormalDof(b.face);
        for (int node : nodes) prescribed.Add(node, normal, 0.0, b.name);
        if (b.pin == Pin::kNone) break;
        // The node sets run along the face from its start.
        const int n = static_cast<int>(nodes.size());
        if (b.pin == Pin::kMiddle && n % 2 == 0) {
          return absl::InvalidArgumentError(absl::StrCat("/boundaries: ", b.name,
                                                         "'s pin \"middle\" needs a node there (",
                                                         n, " nodes along the face)"));
        }
        const int at = b.pin == Pin::kStart ? 0 : b.pin == Pin::kEnd ? n - 1 : (n - 1) / 2;
        prescribed.Add(nodes[at], 1 - normal, 0.0, b.name);
        break;
      }
      case BoundaryKind::kPressure:
        p.boundary.pressures.push_back({mesh.edge_sets.at(FaceSetName(b.face)), b.pressure});
        break;
      case BoundaryKind::kPeriodic:
        periodic = true;  // the pair of faces, once
        break;
      case BoundaryKind::kPlaten:
      case BoundaryKind::kShear:
        return absl::InvalidArgumentError(
            absl::StrCat("/boundaries: ", b.name, ": a second driven face"));
    }
  }
  if (periodic) {
    ASSIGN_OR_RETURN(p.boundary.periodic,
                     MatchPeriodicPairs(mesh, mesh.node_sets.at("left"), mesh.node_sets.at("right"),
                                        /*along=*/1));
  }
  p.boundary.prescribed = prescribed.TakePrescribed();
  p.notes = prescribed.TakeNotes();

  // The checks StaticSolver::Create makes, before any RVE exists.
  absl::StatusOr<DofMap> dofs = DofMap::Create(static_cast<int>(mesh.nodes.size()), p.boundary);
  if (!dofs.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("/boundaries: ", dofs.status().message()));
  }
  if (absl::Status s = CheckSupports(mesh, *dofs); !s.ok()) {
    return absl::FailedPreconditionError(absl::StrCat("/boundaries: ", s.message()));
  }

  p.solver.tangent = CoreTangent(c.solver.tangent);
  p.solver.predictor =
      c.solver.predictor == PredictorKind::kPrevious ? Predictor::kPrevious : Predictor::kZero;
  p.solver.perturbation = c.solver.perturbation;
  p.solver.displacement_tolerance = c.solver.tolerance;
  p.solver.force_tolerance = c.solver.force_tolerance;
  p.solver.second_gradient = c.solver.second_gradient;
  p.solver.max_iterations = c.solver.max_iterations;
  p.solver.max_cutbacks = c.solver.max_cutbacks;
  p.solver.accept_unconverged = c.solver.unconverged == UnconvergedKind::kAccept;
  return p;
}

}  // namespace rvehub::fem
