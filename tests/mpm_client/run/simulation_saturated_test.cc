// The saturated (two-phase) simulation end to end on RVEs: consolidation
// against Terzaghi, a constant rate of strain, a dense column's slow collapse,
// a Rayleigh wave, and resume and remote servers bit-identical.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_join.h"
#include "absl/strings/string_view.h"
#include "client_run/templates.h"
#include "mpm_client/case/case.h"
#include "mpm_client/core/two_phase.h"
#include "mpm_client/run/output.h"
#include "mpm_client/run/simulation.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/engine/element_test.h"
#include "rve_server/service/server.h"
#include "store/results.h"
#include "tests/mpm_client/run/simulation_test_util.h"
#include "tests/support/case_checks.h"
#include "tests/support/test_util.h"

namespace rvehub::mpm::sim_test {
namespace {

// Saturated (liang-zhao-wu-soga-2023 §4.1): consolidation-1d-ci, the column
// of 10 cells with 40 RVEs of the consolidation set, against Terzaghi with
// the RVE's M = 25.08 MPa (rve_cli oedometer) and p0 the load the water
// carries at first (110 kPa less the RVEs' σ'yy, ~10.6 kPa). Measured:
// within 3.55 % of p0 at Tv = 0.041 and 1.7–2.8 % from Tv = 0.10 on (the
// full case, 50 cells: 1.3–2.3 %); Tv = 0.010, where inertia and the coarse
// front show (10.9 %), is left to the full case's figure. The frames carry
// the saturated fields; U from the settlement within 0.05 of Terzaghi's.
TEST(SimulationTest, SaturatedConsolidationFollowsTerzaghi) {
  std::string out;
  const std::map<std::string, std::vector<double>> ts =
      RunSaturatedCase("consolidation-1d-ci", "consolidation", &out);
  ASSERT_FALSE(ts.empty());
  const double p0 = 110e3 - ts.at("mean_syy").front();
  EXPECT_NEAR(p0, 10e3, 0.1 * 10e3);
  const double modulus = 25.08e6, cv = 1e-3 * modulus / (1000.0 * 9.81);
  absl::StatusOr<std::vector<store::ResultFrame>> frames = store::ReadResults(out + "/results.h5");
  ASSERT_TRUE(frames.ok()) << frames.status();
  int checked = 0;
  for (const store::ResultFrame& f : *frames) {
    const double tv = cv * f.time;
    const auto field = std::find_if(f.fields.begin(), f.fields.end(),
                                    [](const auto& x) { return x.name == "pore_pressure"; });
    ASSERT_NE(field, f.fields.end());
    for (const char* name :
         {"excess_pore_pressure", "fluid_velocity", "permeability", "porosity"}) {
      EXPECT_TRUE(std::any_of(f.fields.begin(), f.fields.end(), [&](const auto& x) {
        return x.name == name;
      })) << name;
    }
    if (tv < 0.04) continue;
    ++checked;
    for (std::size_t p = 0; p < field->values.size(); ++p) {
      const double z = 1.0 - f.position[2 * p + 1];
      EXPECT_NEAR(field->values[p], TerzaghiExcessPressure(p0, z, tv), 0.04 * p0)
          << "Tv " << tv << " z " << z;
    }
  }
  EXPECT_EQ(checked, 8);  // Tv = 0.041 … 1.02 and the end
  const std::vector<double>& t = ts.at("time");
  const std::vector<double>& settlement = ts.at("surface_settlement");
  for (std::size_t i = 0; i < t.size(); ++i) {
    const double tv = cv * t[i];
    if (tv < 0.05) continue;
    EXPECT_NEAR(settlement[i] / (p0 / modulus), TerzaghiDegreeOfConsolidation(tv), 0.05)
        << "Tv " << tv;
  }
  EXPECT_GT(ts.at("base_p").back(), 0.0);
  testing_util::ExpectCaseChecksPass(LoadOrDie("consolidation-1d-ci").checks, out);
}

// consolidation-crs-ci: the RVE column under an impermeable rigid platen
// pushed at 1 mm/s, drained through a porous base only. At steady state the
// pore pressure is p(z) = ε̇ γ_w z (2H − z)/(2k) whatever the skeleton's
// stiffness (measured at 1 s: within 2.68 % of its value under the platen at
// every point); the platen carries the total stress, mean σ'yy + mean p
// (measured: to 3e-6), its reaction counting the water's share.
TEST(SimulationTest, SaturatedPlatenConsolidatesAtAConstantRateOfStrain) {
  std::string out;
  const std::map<std::string, std::vector<double>> ts =
      RunSaturatedCase("consolidation-crs-ci", "crs", &out);
  ASSERT_FALSE(ts.empty());
  absl::StatusOr<std::vector<store::ResultFrame>> frames = store::ReadResults(out + "/results.h5");
  ASSERT_TRUE(frames.ok()) << frames.status();
  const store::ResultFrame& last = frames->back();
  EXPECT_NEAR(last.time, 1.0, 1e-3);
  const std::vector<double> pore = FrameField(last, "pore_pressure"),
                            stress = FrameField(last, "stress");
  ASSERT_FALSE(pore.empty());
  ASSERT_EQ(stress.size(), 9 * pore.size());
  const double height = 1.0 + ts.at("platen_dy").back();  // m
  const double rate = 1e-3 / height, k = 1e-3;
  const double p_top = SteadyConstantRateOfStrainPressure(rate, height, height, k, 1000.0);  // Pa
  double mean_p = 0.0, mean_syy = 0.0, worst = 0.0;
  for (std::size_t p = 0; p < pore.size(); ++p) {
    const double z = last.position[2 * p + 1];
    const double exact = SteadyConstantRateOfStrainPressure(rate, height, z, k, 1000.0);
    worst = std::max(worst, std::abs(pore[p] - exact) / p_top);
    mean_p += pore[p] / pore.size();
    mean_syy += stress[9 * p + 4] / pore.size();
  }
  const double load = ts.at("platen_fy").back() / (0.1 * 1.0);  // Pa over the 0.1 m column
  std::printf(
      "CRS with RVEs at 1 s: worst |p - steady| %.2f %% of %.0f Pa; platen %.1f kPa, "
      "mean sigma'yy + p %.1f kPa\n",
      100.0 * worst, p_top, load / 1e3, (mean_p - mean_syy) / 1e3);
  EXPECT_LT(worst, 0.03);
  EXPECT_NEAR(load, mean_p - mean_syy, 1e-3 * load);
  testing_util::ExpectCaseChecksPass(LoadOrDie("consolidation-crs-ci").checks, out);
}

// Saturated column collapse (liang-zhao-wu-soga-2023 §4.3), reduced:
// collapse-saturated-ci, dense SET RVEs, k = 1e-2 m/s, dt = 2e-4 s, F-bar as
// the full columns, to 1.5 s (it blew up at 0.094 s before the free-surface
// nodes were taken as those under 0.9 of soil). The paper's three signs,
// against the dry column with the same Δt and F-bar (column-collapse-ci,
// measured: front point 1.616 m at 0.6 s, kinetic-energy peak 1036 J at
// 0.41 s, main deposit's front point 1.875 m at 1.5 s):
// - the dilating dense column draws the water in: excess pore pressure
//   negative at both monitors from the first steps (measured: Δp/σ'v0 =
//   −1.68 in the middle, −1.11 at the base at 0.06 s);
// - it collapses more slowly (measured: 1.205 m at 0.6 s) and its kinetic
//   energy peaks lower (785 J at 0.65 s);
// - it runs out farther (2.600 m at 1.5 s; both columns still move).
// The bounds sit halfway between the two columns' figures. Its excess pore
// pressure is counted from the current surface (excess_pressure_from): the
// front point, at the drained surface with p ≈ 0, reads −0.64 kPa at 1.5 s,
// not the −9 kPa of the initial water table 0.9 m above it.
TEST(SimulationTest, SaturatedDenseColumnCollapsesSlowlyWithSuction) {
  std::string out;
  const std::map<std::string, std::vector<double>> ts =
      RunSaturatedCase("collapse-saturated-ci", "saturated_collapse", &out);
  ASSERT_FALSE(ts.empty());
  absl::StatusOr<std::vector<store::ResultFrame>> frames = store::ReadResults(out + "/results.h5");
  ASSERT_TRUE(frames.ok()) << frames.status();
  const store::ResultFrame& last = frames->back();
  EXPECT_NEAR(last.time, 1.5, 1e-9);
  const std::vector<double> pore = FrameField(last, "pore_pressure"),
                            excess = FrameField(last, "excess_pore_pressure");
  ASSERT_FALSE(pore.empty());
  ASSERT_EQ(excess.size(), pore.size());
  std::size_t front = 0;  // the point furthest out
  for (std::size_t p = 0; p < pore.size(); ++p) {
    if (last.position[2 * p] > last.position[2 * front]) front = p;
  }
  EXPECT_NEAR(pore[front], 0.0, 100.0);          // Pa: drained surface
  EXPECT_LT(last.position[2 * front + 1], 0.2);  // m: on the base, far below the initial table
  EXPECT_NEAR(excess[front], 0.0, 1000.0);
  const std::vector<double>& t = ts.at("time");
  double peak = 0.0;
  int checked = 0;
  for (std::size_t r = 0; r < t.size(); ++r) {
    peak = std::max(peak, ts.at("kinetic_energy")[r]);
    if (std::abs(t[r] - 0.06) < 1e-6) {
      EXPECT_LT(ts.at("middle_excess_ratio")[r], -0.5) << "t " << t[r];
      EXPECT_LT(ts.at("base_excess_ratio")[r], -0.5) << "t " << t[r];
      ++checked;
    }
    if (std::abs(t[r] - 0.6) < 1e-6) {
      EXPECT_LT(ts.at("front_x")[r], 1.41) << "t " << t[r];  // m; dry 1.616
      ++checked;
    }
  }
  EXPECT_EQ(checked, 2);
  EXPECT_LT(peak, 910.0);                            // J; dry 1036
  EXPECT_GT(ts.at("deposit_front_x").back(), 2.24);  // m; dry 1.875
  // The fronts read by mass lie behind the farthest point, 98 % behind 99 %.
  const std::vector<double>&m98 = ts.at("mass_front_98_x"), &m99 = ts.at("mass_front_99_x");
  for (std::size_t r = 0; r < t.size(); ++r) {
    EXPECT_LE(m98[r], m99[r]) << "t " << t[r];
    EXPECT_LE(m99[r], ts.at("front_x")[r]) << "t " << t[r];
  }
  EXPECT_GT(m98.back(), 2.0);  // m: the flow moved them
  testing_util::ExpectCaseChecksPass(LoadOrDie("collapse-saturated-ci").checks, out);
}

// §4.4, wave-propagation-ci: a half-sine pulse (eq. 38) on the surface of a
// saturated half-space sends a surface wave outwards. Its trough reaches the
// surface points 3 and 7 m from the load 4 m / c apart; c must lie within
// 15 % of Rayleigh's speed for the RVE's measured moduli (M ≈ 56 MPa,
// G ≈ 25 MPa, ρ_sat = 2392 kg/m³: c_s = 102 m/s, c_R = 91.2 m/s drained,
// 97.7 undrained; cases/wave_compare.py). The band holds G's spread between
// strains of 1e-4 and 4e-4 (±8 % in c) and the coarse mesh's dispersion
// (measured: 84.4 m/s here, 82.0 on the paper's mesh); the P-wave (153 m/s)
// or a standing load would fall outside it. At k = 1e-2 m/s the load point
// drains while loaded: its excess pore pressure peaks before the load's
// maximum at 0.02 s, as the paper reports (Fig. 19b), and its settlement
// mostly recovers once the pulse has passed (an elastic response). The
// case's check reads the same speed from the traces' cross-correlation (the
// wave summary): the same band.
TEST(SimulationTest, SaturatedImpulseSendsARayleighWave) {
  std::string out;
  const std::map<std::string, std::vector<double>> ts =
      RunSaturatedCase("wave-propagation-ci", "wave", &out);
  ASSERT_FALSE(ts.empty());
  const std::vector<double>& t = ts.at("time");
  // The first trough of u_y at a monitor, before reflections (0.12 s).
  auto trough = [&](const std::string& column) {
    const std::vector<double>& u = ts.at(column);
    std::size_t best = 0;
    for (std::size_t r = 0; r < t.size() && t[r] < 0.12; ++r) {
      if (u[r] < u[best]) best = r;
    }
    return best;
  };
  const double speed = 4.0 / (t[trough("R7_uy")] - t[trough("R3_uy")]);
  const double rayleigh = 91.2;  // m/s, drained
  std::printf("surface wave R3 -> R7: %.1f m/s (%.3f x Rayleigh's %.1f m/s)\n", speed,
              speed / rayleigh, rayleigh);
  EXPECT_NEAR(speed / rayleigh, 1.0, 0.15);

  const std::size_t b_low = trough("B_uy");
  const std::vector<double>& b_p = ts.at("B_p");
  const std::size_t b_peak = std::max_element(b_p.begin(), b_p.end()) - b_p.begin();
  std::printf("B: u_y %.3f mm at %.4f s, %.3f mm at the end; excess p peak %.2f kPa at %.4f s\n",
              1e3 * ts.at("B_uy")[b_low], t[b_low], 1e3 * ts.at("B_uy").back(), 1e-3 * b_p[b_peak],
              t[b_peak]);
  EXPECT_LT(ts.at("B_uy")[b_low], -1e-3);
  EXPECT_LT(std::abs(ts.at("B_uy").back()), 0.2 * std::abs(ts.at("B_uy")[b_low]));
  EXPECT_GT(b_p[b_peak], 0.0);
  EXPECT_LT(t[b_peak], 0.02);
  testing_util::ExpectCaseChecksPass(LoadOrDie("wave-propagation-ci").checks, out);
}

// A saturated run resumes bit for bit and runs alike on two servers.
// The excess pore pressure ratio's σ'yy,0 is each point's geostatic
// effective stress γ'·z, not the 2 kPa floor (initial_stress.minimum) its
// RVE was consolidated to: near the surface the floor lifts the RVE, not
// the ratio's denominator.
TEST(SimulationTest, ExcessRatioIsTakenAgainstTheGeostaticStressNotTheFloor) {
  CaseSpec spec = LoadOrDie("collapse-saturated-ci");
  std::unique_ptr<Simulation> sim = StartOrDie(spec, Options(FreshDir("sat_sv0")));
  ASSERT_NE(sim, nullptr);
  absl::StatusOr<store::SimCheckpoint> start = sim->Snapshot();
  ASSERT_TRUE(start.ok()) << start.status();
  const std::vector<double>& sv0 = start->doubles.at("vertical_stress0");
  const std::vector<double>& position = start->doubles.at("position");
  const std::vector<double>& stress = start->doubles.at("stress");
  ASSERT_EQ(position.size(), 2 * sv0.size());
  const double surface = spec.regions.front().surface_y;  // m
  // γ' = (ρ_d − (1 − n0)·ρ_f)·g, the solid's mass per volume less the water
  // it displaces: one value for the region (its template's porosity), within
  // 1 % of a point's (its own RVE's porosity after consolidation).
  const double gamma = sv0[0] / (surface - position[1]);  // N/m³
  const double g = spec.solver.gravity.norm();            // m/s²
  const double n0 = start->doubles.at("porosity0")[0];
  const double dry = start->doubles.at("mass")[0] / start->doubles.at("volume")[0];  // kg/m³
  EXPECT_NEAR(gamma, (dry - (1.0 - n0) * spec.phases.fluid_density) * g, 0.01 * gamma);
  int lifted = 0;
  for (std::size_t p = 0; p < sv0.size(); ++p) {
    const double depth = surface - position[2 * p + 1];  // m
    EXPECT_NEAR(sv0[p], gamma * depth, 1e-9 * gamma) << "point " << p;
    if (gamma * depth < 2000.0) {
      ++lifted;
      EXPECT_GT(-stress[9 * p + 4], 1900.0) << "point " << p << ": its RVE at the floor";
    }
  }
  EXPECT_GT(lifted, 0);
}

TEST(SimulationTest, SaturatedResumeAndRemoteAreBitIdentical) {
  setenv("GRPC_CLIENT_CHANNEL_BACKUP_POLL_INTERVAL_MS", "50", 1);
  CaseSpec spec = LoadOrDie("consolidation-1d-ci");
  spec.solver.end_time = 40 * 4e-4;
  spec.output.frame_times.clear();
  spec.output.frame_every = 10;
  std::unique_ptr<Simulation> a = StartOrDie(spec, Options(FreshDir("sat_a")));
  ASSERT_NE(a, nullptr);
  ASSERT_TRUE(a->StepToEnd().ok());
  absl::StatusOr<store::SimCheckpoint> end_a = a->Snapshot();
  ASSERT_TRUE(end_a.ok()) << end_a.status();
  ASSERT_TRUE(end_a->doubles.contains("pore_pressure"));

  absl::StatusOr<store::SimCheckpoint> end_c = StopAndResume(spec, "sat_b", 15);
  ASSERT_TRUE(end_c.ok()) << end_c.status();
  ExpectSameSnapshots(*end_a, *end_c);

  absl::StatusOr<store::SimCheckpoint> two = RunOnTwoLoopbackServers(spec, "sat_two");
  ASSERT_TRUE(two.ok()) << two.status();
  ExpectSameSnapshots(*end_a, *two);
}

}  // namespace
}  // namespace rvehub::mpm::sim_test
