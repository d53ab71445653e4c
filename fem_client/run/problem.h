// A FemCase as the solver's problem: the mesh of its rectangle, the
// boundary conditions of its faces, the load factor of every load step and
// what the outputs measure (the driven face, the lateral face). Pure: no
// RVEs, no files.
//
// Gauss points: the core numbers them element by element (elements row by
// row from the lower left, e = i + nx·j), each element's in its
// GaussPoints() order (ξ fastest), which is the case's documented numbering
// (cases/FEM_FORMAT.md, "Gauss point ids"): Gauss point k is RVE k, with no
// mapping between the two.
#ifndef RVEHUB_FEM_CLIENT_RUN_PROBLEM_H_
#define RVEHUB_FEM_CLIENT_RUN_PROBLEM_H_

#include <Eigen/Dense>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "fem_client/case/fem_case.h"
#include "fem_client/core/boundary.h"
#include "fem_client/core/mesh.h"
#include "fem_client/core/static_solver.h"

namespace rvehub::fem {

// The mesh's node set and edge set of a face: "left", "right", "bottom", "top".
std::string FaceSetName(Face face);
// The face's outward unit normal, and its unit tangent (+x along the bottom
// and top, +y along the left and right).
Eigen::Vector2d OutwardNormal(Face face);
Eigen::Vector2d FaceTangent(Face face);

struct Problem {
  Mesh mesh;
  Boundary boundary;  // increments of a load step at factor 1, m
  SolverOptions solver;
  // The driven face: the platen or the shear platen.
  Face driven = Face::kTop;
  // The specimen's initial length across the driven face (its height for a
  // face on the top or bottom), m: the nominal strains' gauge length.
  double length_across = 1.0;
  // The face whose normal stress the timeseries calls the lateral stress:
  // under compression the right face (or the top, for a platen on the left
  // or right), as G&Z §3.3 take σ00 on the right boundary; under shear the
  // shear platen itself (its normal stress σyy).
  Face lateral = Face::kRight;
  bool shear = false;  // the loading moves the shear platen (τ, γ), not a platen (σ, ε)
  // The shear platen driven by its force (stress-controlled cycles:
  // Boundary::forced[0]), not by its displacement.
  bool forced = false;
  // The load factor of every step, in order (Step(factor)): 1 for
  // monotonic loadings; ±1 by the quarter for strain-controlled cycles.
  std::vector<double> factors;
  // Set-up facts worth a log line (a corner two boundaries claim).
  std::vector<std::string> notes;
};

// The problem of a case ParseFemCase accepted: its mesh (StructuredRectangle),
// boundary and load steps, checked as the solver will check them (the
// constraints, the supports against rigid-body motion), so that a case that
// cannot run fails here, before any RVE exists. Boundaries:
// - the driven face first: a compression platen moves every node of its face
//   by the step's axial strain × length_across into the specimen (smooth:
//   the normal displacement only; rough: the tangential held too); the shear
//   platen moves its face by the step's shear strain × the height along +x
//   and holds its height;
// - then the others, each (node, dof) at most once: a corner the driven face
//   already moves keeps the platen's motion (a note when a support would
//   have held it); fixed, both dofs held; roller, the normal one (and at a
//   pin, both); pressure, a follower load normal to the face's edges
//   (compression +); periodic, the right face's nodes tied to the left's at
//   equal heights.
absl::StatusOr<Problem> BuildProblem(const FemCase& c);

}  // namespace rvehub::fem

#endif  // RVEHUB_FEM_CLIENT_RUN_PROBLEM_H_
