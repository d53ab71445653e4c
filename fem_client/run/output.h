// fem_client's plain-text outputs: the columns of timeseries.csv, the
// headline figures (summary.json) and the standard plot (plot.png), both
// drawn from timeseries.csv alone, so that `fem_client summarise` writes
// them again exactly as the run did.
//
// Signs: stresses compression positive (Pa), strains compression positive
// ([-]), τ and γ positive towards +x (cases/FEM_FORMAT.md, Conventions).
#ifndef RVEHUB_FEM_CLIENT_RUN_OUTPUT_H_
#define RVEHUB_FEM_CLIENT_RUN_OUTPUT_H_

#include <map>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "client_run/summary.h"
#include "fem_client/case/fem_case.h"

namespace rvehub::fem {

using client_run::Summary;

// timeseries.csv's columns, one row per recorded load step (row 0: the
// RVEs' initial state, before any step):
//   step                       load steps done
//   axial_strain               the driven face's normal travel into the specimen
//                              over the specimen's initial length across it, [-]
//   vol_strain                 1 − A/A0 of the mesh's area, [-]
//   shear_strain               γ: the driven face's mean travel along it (+x on the
//                              top) relative to the face across, over the same
//                              length, [-]
//   platen_force_per_width_Pa  compression: the platen's force on the specimen
//                              (the reaction of its face, normal, compression +)
//                              over the face's current length; shear: τ, the
//                              shear platen's horizontal force on the specimen over
//                              its current width (+ towards +x), Pa
//   lateral_stress_Pa          the lateral face's normal stress: the body's force
//                              on it (Σ f_int) over its current length,
//                              compression + (under shear: σyy on the platen), Pa
//   mean_p_Pa, mean_q_Pa       p and q of the Gauss points' mean stress (weighted
//                              by their current volumes), Pa
//   mean_void_ratio            likewise, [-]
//   iterations                 Newton iterations of the step (all its sub-steps)
//   error_d, error_f           E_d and E_f of its last iteration (G&Z eq. 21)
//   cutbacks                   halvings the step needed
//   unconverged                its sub-steps committed without converging
//                              (solver.unconverged "accept")
//   trials                     the step's TRIAL calls over every RVE (iterations,
//                              failed attempts and perturbations)
//   dem_steps_per_trial        DEM steps per RVE per TRIAL in the step, mean
//   wall_step_s                wall time of the step and its outputs, s (the one
//                              column that differs between equal runs)
//   gp<k>_sxx_Pa, gp<k>_syy_Pa, gp<k>_sxy_Pa, gp<k>_void_ratio
//                              Gauss point k's stress (compression +, Pa) and void
//                              ratio, for each k of output.monitor
// Row 0 has no step: its solver columns are 0 and its platen and lateral
// stresses the Gauss points' mean normal stresses on those faces.
std::vector<std::string> TimeseriesColumns(const FemCase& c);

// The figures of a run from its timeseries columns, in summary.json's
// order. Compression: peak_stress_Pa and peak_strain (the largest nominal
// platen stress, platen_force_per_width_Pa against axial_strain, as
// mpm_client's biaxial summary reads its curve), final_stress_Pa,
// final_strain. Shear: peak_shear_stress_Pa and peak_shear_strain (the
// largest τ), min_shear_stress_Pa, final_shear_strain, final_mean_p_Pa,
// max_abs_shear_strain (the largest |γ| of any row) and, for cyclic shear,
// cycles (the last row's step over steps_per_cycle). Then
// over the rows after row 0: load_steps (the last row's step), iterations_mean
// and iterations_max per step, iterations_total, cutbacks_total,
// unconverged_total, trials_total, dem_steps_per_trial (the mean over the rows' TRIALs) and
// wall_s (Σ wall_step_s: the stepping's wall time). InvalidArgument naming a
// column the timeseries lacks or a timeseries without steps.
absl::StatusOr<Summary> SummariseFem(const FemCase& c,
                                     const std::map<std::string, std::vector<double>>& columns);

// What a finished run (and `fem_client summarise`) writes from
// DIR/timeseries.csv, read once: DIR/summary.json (SummariseFem) and
// DIR/plot.png, the case's plot (output.plot): "stress-strain": the nominal
// platen stress and the volumetric strain against the axial strain (G&Z
// Fig. 6), with the case's reference curve (an rve_cli element-test CSV:
// its syy and vol_strain against axial_strain) as "DEM element test", and
// the Newton iterations per step; "simple-shear": τ against γ (with the
// reference's −sxy, its σxy, against shear_strain) and τ against the mean p
// (G&Z Figs. 20, 22); "none": no plot. Returns the figures.
absl::StatusOr<Summary> WriteFemRunOutputs(const FemCase& c, const std::string& dir);

}  // namespace rvehub::fem

#endif  // RVEHUB_FEM_CLIENT_RUN_OUTPUT_H_
