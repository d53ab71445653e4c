// Plain data describing a fem_client case (cases/FEM_FORMAT.md): implicit
// quasi-static plane-strain FEM×DEM after Guo & Zhao 2014 on a structured
// rectangular mesh, one RVE per Gauss point. x to the right, y up, SI units;
// pressures and stresses in this struct are compression positive, as in the
// file. The case reader fills it (case.h).
#ifndef RVEHUB_FEM_CLIENT_CASE_FEM_CASE_H_
#define RVEHUB_FEM_CLIENT_CASE_FEM_CASE_H_

#include <Eigen/Dense>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "client_case/spec/check_spec.h"
#include "client_case/spec/rve_spec.h"

namespace rvehub::fem {

// The RVE templates and controls, as every continuum client's case holds them.
using client_case::CheckSpec;
using client_case::RveSpec;
using client_case::TemplateSpec;

enum class ElementKind {
  kQ4,   // bilinear quadrilateral, 2×2 Gauss points
  kQ8,   // serendipity quadrilateral, 3×3 Gauss points
  kQ8R,  // serendipity quadrilateral, 2×2 Gauss points: the second-gradient element
};

// A rectangle of nx × ny equal elements. Elements are numbered row by row
// from the lower left (e = i + nx·j); a Gauss point's id is
// e·(points per element) + g, g counting the element's tensor-product
// points row by row from its lower left (ξ fastest).
struct MeshSpec {
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();  // m, lower-left corner
  Eigen::Vector2d size = Eigen::Vector2d::Ones();    // m, [width, height]
  int nx = 1;                                        // elements along x
  int ny = 1;                                        // elements along y
  ElementKind element = ElementKind::kQ4;
};

// 4 for Q4 and Q8R, 9 for Q8.
int GaussPointsPerElement(ElementKind kind);
// nx·ny·GaussPointsPerElement: the mesh's RVEs.
std::int64_t GaussPointCount(const MeshSpec& mesh);

// Where every Gauss point's RVE starts: the template's own state (its
// preparation pressure), an isotropic pressure, or σyy with σxx = K0·σyy.
enum class InitialStressKind { kTemplate, kIsotropic, kK0 };

// The one material of the mesh: every Gauss point's RVE is created from the
// same template and consolidated to the same initial stress.
struct MaterialSpec {
  std::string rve_template;  // a TemplateSpec's name
  InitialStressKind initial_stress = InitialStressKind::kTemplate;
  double pressure = 0.0;  // Pa, compression +: p of kIsotropic
  double vertical = 0.0;  // Pa, compression +: σyy of kK0
  double k0 = 0.5;        // σxx/σyy of kK0, [-]
};

// The mesh's faces: x = origin.x (left), x = origin.x + width (right),
// y = origin.y (bottom), y = origin.y + height (top).
enum class Face { kLeft, kRight, kBottom, kTop };

enum class BoundaryKind {
  kFixed,     // both displacements held at zero
  kRoller,    // the normal displacement held at zero, the tangential free
  kPlaten,    // a rigid platen driven into the specimen by the loading
  kPressure,  // a constant pressure normal to the face
  kPeriodic,  // left and right paired node by node: u(right) = u(left)
  kShear,     // the top as a rough rigid platen: its horizontal motion (or
              // force) prescribed by the loading, its height held
};

// How a platen holds its face: smooth, the normal displacement only (the
// face slides freely along it); rough, both (no slip).
enum class Contact { kSmooth, kRough };

// A roller's one node also held along the face (so held in full), to take
// the rigid-body translation a smooth face leaves: the node at the face's
// start (lowest x or y), its middle or its end.
enum class Pin { kNone, kStart, kMiddle, kEnd };

// A condition on one face of the mesh; a face without one is traction-free.
struct BoundarySpec {
  std::string name;
  Face face = Face::kLeft;
  BoundaryKind kind = BoundaryKind::kFixed;
  Contact contact = Contact::kSmooth;  // kPlaten only
  double pressure = 0.0;               // Pa, compression +, kPressure only
  Pin pin = Pin::kNone;                // kRoller only
};

enum class LoadingKind {
  kCompression,  // the platen driven to an axial strain
  kShear,        // the shear platen driven to a shear strain
  kCyclicShear,  // the shear platen cycled under strain or stress control
};

// Cyclic shear's amplitude: a shear strain γ or a shear stress |τ|.
enum class CyclicControl { kStrain, kStress };

// The load steps. Strains are nominal: the axial strain is the platen's
// travel over the specimen's initial length across it (compression +); the
// shear strain γ is the top's horizontal displacement over the initial
// height (+ when the top moves towards +x); the shear stress τ is the
// platen's horizontal force on the specimen over its initial width, per unit
// thickness (+ towards +x: σxy on the top face). A cycle goes 0 → +A → −A →
// 0 in four equal quarters.
struct LoadingSpec {
  LoadingKind kind = LoadingKind::kCompression;
  // kCompression: the axial strain at the end; kShear: the shear strain at
  // the end; kCyclicShear with stress control: the run stops once |γ|
  // reaches it (+∞: after the cycles), [-].
  double end_strain = std::numeric_limits<double>::infinity();
  // kCompression, kShear: equal load steps to end_strain (end_strain/steps
  // each).
  std::int64_t steps = 0;
  CyclicControl control = CyclicControl::kStrain;  // kCyclicShear only
  double amplitude = 0.0;  // kCyclicShear: γ_a [-] (strain) or τ_a Pa (stress)
  int cycles = 0;          // kCyclicShear
  // kCyclicShear: load steps per cycle, a multiple of 4 (each an equal step
  // of γ or τ, 4·amplitude/steps_per_cycle, so every peak is a step's end).
  std::int64_t steps_per_cycle = 0;
};

// How the global tangent is built from the RVEs (G&Z §2.2).
enum class TangentKind {
  kContact,         // from each RVE's contacts (G&Z eq. 9), updated every iteration
  kPerturbation,    // finite differences of each RVE's stress (G&Z eq. 8): 4 trials
  kInitialElastic,  // the contact tangent at the start, kept throughout
};

// Where each load step's Newton iterations start (core Predictor).
enum class PredictorKind {
  kZero,      // Δu = 0, the prescribed increments through the first solve (G&Z)
  kPrevious,  // the last converged increment, scaled: one extra Trial per step
};

// What a sub-step whose Newton iterations run out does.
enum class UnconvergedKind {
  kStop,    // cut back; the run stops once the cut-backs run out
  kAccept,  // commit the last iterate and go on (counted in the outputs)
};

struct SolverSpec {
  TangentKind tangent = TangentKind::kContact;
  // The previous increment: 2.3 times fewer TRIALs than a zero start on the
  // single element test, the same residual forces at convergence.
  PredictorKind predictor = PredictorKind::kPrevious;
  double perturbation = 5e-5;  // ξ of kPerturbation, a strain, [-]
  // E_d = |u^j − u^(j−1)| / |u^j| (G&Z eq. 21) below which an iteration
  // has converged, [-].
  double tolerance = 0.01;
  // When > 0, the force error E_f = |R| / |f| must also be below it, [-].
  double force_tolerance = 0.0;
  int max_iterations = 30;  // Newton iterations of a step before it is cut back
  int max_cutbacks = 6;     // halvings of one step before the run stops
  UnconvergedKind unconverged = UnconvergedKind::kStop;
  // D of the local second gradient (Desrues et al. eq. 44), N (Pa·m² per
  // metre of thickness); 0: none. Needs Q8R elements.
  double second_gradient = 0.0;
};

// The standard plot of a finished run: the nominal stress and volumetric
// strain against the axial strain; or τ against γ and τ against the mean
// effective stress (a simple shear's loops).
enum class PlotKind { kStressStrain, kSimpleShear, kNone };

struct OutputSpec {
  std::int64_t timeseries_every = 1;   // load steps between timeseries rows
  std::int64_t frame_every = 10;       // load steps between frames (every Gauss point)
  std::int64_t checkpoint_every = 0;   // load steps between checkpoints; 0: none
  std::int64_t progress_every = 1;     // load steps between progress lines
  std::vector<std::int64_t> monitor;   // Gauss point ids recorded in the timeseries
  std::vector<std::int64_t> packings;  // Gauss point ids whose packings frames write
  PlotKind plot = PlotKind::kStressStrain;
  // An `rve_cli element-test` CSV (absolute path; the case file may give it
  // relative to itself) drawn on the plot as the DEM element test on the same
  // RVE.
  std::string reference_curve;
};

struct FemCase {
  std::string name;
  std::string description;
  double expected_runtime_s = 0.0;  // s, on a 2-core machine, embedded servers
  MeshSpec mesh;
  std::vector<TemplateSpec> templates;
  MaterialSpec material;
  RveSpec rve;
  std::vector<BoundarySpec> boundaries;
  LoadingSpec loading;
  SolverSpec solver;
  OutputSpec output;
  // What the run's summary.json is compared with (`fem_client summarise`).
  std::vector<CheckSpec> checks;
};

}  // namespace rvehub::fem

#endif  // RVEHUB_FEM_CLIENT_CASE_FEM_CASE_H_
