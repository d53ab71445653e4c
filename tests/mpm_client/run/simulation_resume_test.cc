// Resuming a simulation from its checkpoint: bit-identical continuations,
// later end times and smaller CFL numbers, settings the checkpoint carries,
// resumes refused, and a time step updated from the RVEs.
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
#include "tests/support/test_util.h"

namespace rvehub::mpm::sim_test {
namespace {

TEST(SimulationTest, ResumeFromCheckpointIsBitIdentical) {
  const CaseSpec spec = ShortCase(40);
  // Uninterrupted.
  std::unique_ptr<Simulation> a = StartOrDie(spec, Options(FreshDir("resume_a")));
  ASSERT_NE(a, nullptr);
  ASSERT_TRUE(a->StepToEnd().ok());
  absl::StatusOr<store::SimCheckpoint> end_a = a->Snapshot();
  ASSERT_TRUE(end_a.ok()) << end_a.status();

  // Interrupted after 25 steps (checkpoint written there), then resumed.
  CaseSpec with_checkpoints = spec;
  with_checkpoints.output.checkpoint_every = 10;
  const std::string out_b = FreshDir("resume_b");
  SimulationOptions ob = Options(out_b);
  ob.stop_after_steps = 25;
  {
    std::unique_ptr<Simulation> b = StartOrDie(with_checkpoints, ob);
    ASSERT_NE(b, nullptr);
    absl::StatusOr<SimulationSummary> s = b->StepToEnd();
    ASSERT_TRUE(s.ok()) << s.status();
    EXPECT_FALSE(s->finished);
    EXPECT_EQ(s->final_step, 25);
  }
  ob.stop_after_steps = 0;
  absl::StatusOr<std::unique_ptr<Simulation>> c = Simulation::Resume(out_b + "/checkpoint.h5", ob);
  ASSERT_TRUE(c.ok()) << c.status();
  EXPECT_EQ((*c)->solver().step(), 25);
  absl::StatusOr<SimulationSummary> s = (*c)->StepToEnd();
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_TRUE(s->finished);
  absl::StatusOr<store::SimCheckpoint> end_c = (*c)->Snapshot();
  ASSERT_TRUE(end_c.ok()) << end_c.status();
  ExpectSameSnapshots(*end_a, *end_c);

  // The resumed run's outputs hold every frame and row once, in order.
  absl::StatusOr<std::vector<store::ResultFrame>> frames =
      store::ReadResults(out_b + "/results.h5");
  ASSERT_TRUE(frames.ok()) << frames.status();
  std::vector<std::int64_t> steps;
  for (const auto& f : *frames) steps.push_back(f.step);
  EXPECT_EQ(steps, (std::vector<std::int64_t>{0, 10, 20, 30, 40}));
  absl::StatusOr<std::map<std::string, std::vector<double>>> ts =
      ReadCsvColumns(out_b + "/timeseries.csv");
  ASSERT_TRUE(ts.ok()) << ts.status();
  EXPECT_EQ(ts->at("step"), (std::vector<double>{0, 5, 10, 15, 20, 25, 30, 35, 40}));
}

// Between outputs the RVEs measure the stress alone (ApplyOptions::
// stress_only, rve.full_state_every_step off): the frames (regular and one
// due at a frame time between them), the timeseries and the end state are
// those of a run that measures every RVE in full at every step, bit for bit.
TEST(SimulationTest, StressOnlyBetweenOutputsChangesNoResult) {
  CaseSpec lean = ShortCase(40);
  lean.output.frame_times = {0.031};  // due at step 15, between the regular frames
  CaseSpec full = lean;
  full.rve.full_state_every_step = true;
  const std::string out_lean = FreshDir("stress_only_lean"),
                    out_full = FreshDir("stress_only_full");
  std::unique_ptr<Simulation> a = StartOrDie(lean, Options(out_lean));
  std::unique_ptr<Simulation> b = StartOrDie(full, Options(out_full));
  ASSERT_NE(a, nullptr);
  ASSERT_NE(b, nullptr);
  ASSERT_TRUE(a->StepToEnd().ok());
  ASSERT_TRUE(b->StepToEnd().ok());
  absl::StatusOr<store::SimCheckpoint> end_a = a->Snapshot();
  absl::StatusOr<store::SimCheckpoint> end_b = b->Snapshot();
  ASSERT_TRUE(end_a.ok()) << end_a.status();
  ASSERT_TRUE(end_b.ok()) << end_b.status();
  ExpectSameSnapshots(*end_a, *end_b);
  absl::StatusOr<std::vector<store::ResultFrame>> fa = store::ReadResults(out_lean + "/results.h5");
  absl::StatusOr<std::vector<store::ResultFrame>> fb = store::ReadResults(out_full + "/results.h5");
  ASSERT_TRUE(fa.ok()) << fa.status();
  ASSERT_TRUE(fb.ok()) << fb.status();
  ASSERT_EQ(fa->size(), fb->size());
  std::vector<std::int64_t> steps;
  for (std::size_t k = 0; k < fa->size(); ++k) {
    steps.push_back((*fa)[k].step);
    ASSERT_EQ((*fa)[k].fields.size(), (*fb)[k].fields.size());
    for (const store::ResultField& f : (*fa)[k].fields) {
      dem::testing_util::ExpectSameBits(f.values, FrameField((*fb)[k], f.name),
                                        ("frame " + std::to_string(k) + " " + f.name).c_str());
    }
  }
  EXPECT_EQ(steps, (std::vector<std::int64_t>{0, 10, 15, 20, 30, 40}));
  // The frames carry the fabric: measured at the frame's step, not left at 0.
  const std::vector<double> fabric = FrameField((*fa)[2], "fabric_anisotropy");
  ASSERT_FALSE(fabric.empty());
  EXPECT_GT(fabric[0], 0.0);
  absl::StatusOr<std::map<std::string, std::vector<double>>> ta =
      ReadCsvColumns(out_lean + "/timeseries.csv");
  absl::StatusOr<std::map<std::string, std::vector<double>>> tb =
      ReadCsvColumns(out_full + "/timeseries.csv");
  ASSERT_TRUE(ta.ok()) << ta.status();
  ASSERT_TRUE(tb.ok()) << tb.status();
  for (const auto& [name, values] : *ta) {
    if (name == "wall_per_step_s") continue;
    ASSERT_TRUE(tb->contains(name)) << name;
    dem::testing_util::ExpectSameBits(values, tb->at(name), name.c_str());
  }
}

// rve.max_stretch reaches the controls of every RVE the case creates (and so
// its checkpoint); without it they keep the template's 0.05.
TEST(SimulationTest, StretchBoundReachesEveryRve) {
  CaseSpec spec = ShortCase(1);
  for (const double bound : {0.0, 0.3}) {
    SCOPED_TRACE(bound);
    spec.rve.max_stretch = bound;
    std::unique_ptr<Simulation> sim =
        StartOrDie(spec, Options(FreshDir("stretch_bound_" + std::to_string(bound > 0))));
    ASSERT_NE(sim, nullptr);
    absl::StatusOr<store::SimCheckpoint> snap = sim->Snapshot();
    ASSERT_TRUE(snap.ok()) << snap.status();
    ASSERT_EQ(snap->rves.size(), 4u);
    for (const RveRecord& r : snap->rves) {
      EXPECT_EQ(r.packing.controls.max_stretch, bound > 0 ? bound : 0.05) << r.id;
    }
  }
}

// A finished run resumed with a later end time goes on as if the case had
// asked for it: bit-identical to the longer run, and its checkpoint carries
// the new end time. An end time not after the checkpoint's is refused.
TEST(SimulationTest, ResumeWithALaterEndTimeExtendsTheRun) {
  double dt = 0;
  const CaseSpec longer = ShortCase(40, &dt);
  std::unique_ptr<Simulation> a = StartOrDie(longer, Options(FreshDir("extend_a")));
  ASSERT_NE(a, nullptr);
  ASSERT_TRUE(a->StepToEnd().ok());
  absl::StatusOr<store::SimCheckpoint> end_a = a->Snapshot();
  ASSERT_TRUE(end_a.ok()) << end_a.status();

  CaseSpec shorter = ShortCase(25);
  shorter.output.checkpoint_every = 25;
  const std::string out_b = FreshDir("extend_b");
  {
    std::unique_ptr<Simulation> b = StartOrDie(shorter, Options(out_b));
    ASSERT_NE(b, nullptr);
    absl::StatusOr<SimulationSummary> s = b->StepToEnd();
    ASSERT_TRUE(s.ok()) << s.status();
    EXPECT_TRUE(s->finished);
    EXPECT_EQ(s->final_step, 25);
  }
  SimulationOptions too_early = Options(out_b);
  too_early.end_time = 25 * dt;
  absl::StatusOr<std::unique_ptr<Simulation>> refused =
      Simulation::Resume(out_b + "/checkpoint.h5", too_early);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(absl::StrContains(refused.status().message(),
                                "--end-time 0.05 s is not after the checkpoint's time 0.05 s"))
      << refused.status();

  SimulationOptions later = Options(out_b);
  later.end_time = longer.solver.end_time;
  absl::StatusOr<std::unique_ptr<Simulation>> c =
      Simulation::Resume(out_b + "/checkpoint.h5", later);
  ASSERT_TRUE(c.ok()) << c.status();
  absl::StatusOr<SimulationSummary> s = (*c)->StepToEnd();
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_TRUE(s->finished);
  EXPECT_EQ(s->final_step, 40);
  absl::StatusOr<store::SimCheckpoint> end_c = (*c)->Snapshot();
  ASSERT_TRUE(end_c.ok()) << end_c.status();
  ExpectSameSnapshots(*end_a, *end_c);
  absl::StatusOr<CaseSpec> carried = ParseCase(end_c->case_json, ".");
  ASSERT_TRUE(carried.ok()) << carried.status();
  EXPECT_EQ(carried->solver.end_time, longer.solver.end_time);
}

// A run resumed with --cfl goes on with its time step scaled by the ratio of
// the CFL numbers (exactly: 0.25/0.5), and its later checkpoints carry the new
// number and step, so a second resume keeps them. A case with a fixed step
// has no CFL number to change.
TEST(SimulationTest, ResumeWithASmallerCflHalvesTheTimeStep) {
  CaseSpec spec = ShortCase(20);
  spec.solver.time_step = 0;  // from the CFL number and the RVE's tangent
  spec.solver.cfl = 0.5;
  spec.solver.end_time = 1.0;
  const std::string out = FreshDir("cfl_resume");
  SimulationOptions o = Options(out);
  o.stop_after_steps = 10;
  double dt = 0;
  {
    std::unique_ptr<Simulation> a = StartOrDie(spec, o);
    ASSERT_NE(a, nullptr);
    dt = a->solver().dt();
    ASSERT_GT(dt, 0);
    ASSERT_TRUE(a->StepToEnd().ok());
  }
  o.stop_after_steps = 5;
  o.cfl = 0.25;
  const double t10 = 10 * dt;
  {
    absl::StatusOr<std::unique_ptr<Simulation>> b = Simulation::Resume(out + "/checkpoint.h5", o);
    ASSERT_TRUE(b.ok()) << b.status();
    EXPECT_EQ((*b)->solver().dt(), 0.5 * dt);
    absl::StatusOr<SimulationSummary> s = (*b)->StepToEnd();
    ASSERT_TRUE(s.ok()) << s.status();
    EXPECT_EQ(s->final_step, 15);
    EXPECT_NEAR(s->final_time, t10 + 5 * 0.5 * dt, 1e-12 * t10);
  }
  absl::StatusOr<store::SimCheckpoint> c = store::ReadSimCheckpoint(out + "/checkpoint.h5");
  ASSERT_TRUE(c.ok()) << c.status();
  absl::StatusOr<CaseSpec> carried = ParseCase(c->case_json, ".");
  ASSERT_TRUE(carried.ok()) << carried.status();
  EXPECT_EQ(carried->solver.cfl, 0.25);
  o.cfl = 0;
  absl::StatusOr<std::unique_ptr<Simulation>> again = Simulation::Resume(out + "/checkpoint.h5", o);
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_EQ((*again)->solver().dt(), 0.5 * dt);

  const std::string fixed_out = FreshDir("cfl_fixed");
  SimulationOptions f = Options(fixed_out);
  f.stop_after_steps = 2;
  {
    std::unique_ptr<Simulation> a = StartOrDie(ShortCase(20), f);
    ASSERT_NE(a, nullptr);
    ASSERT_TRUE(a->StepToEnd().ok());
  }
  f.cfl = 0.25;
  absl::StatusOr<std::unique_ptr<Simulation>> refused =
      Simulation::Resume(fixed_out + "/checkpoint.h5", f);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(absl::StrContains(refused.status().message(),
                                "--cfl: this run's case fixes solver.time_step = 0.002 s"))
      << refused.status();
}

// ShortCase(20) stopped after 4 steps in `out`, then resumed there with `o`
// to the end: the case the final checkpoint carries.
std::optional<CaseSpec> ResumedAndCarried(const std::string& out, SimulationOptions o) {
  absl::StatusOr<std::unique_ptr<Simulation>> b = Simulation::Resume(out + "/checkpoint.h5", o);
  EXPECT_TRUE(b.ok()) << b.status();
  if (!b.ok()) return std::nullopt;
  const absl::Status run = (*b)->StepToEnd().status();
  EXPECT_TRUE(run.ok()) << run;
  b->reset();
  absl::StatusOr<store::SimCheckpoint> c = store::ReadSimCheckpoint(out + "/checkpoint.h5");
  EXPECT_TRUE(c.ok()) << c.status();
  if (!c.ok()) return std::nullopt;
  absl::StatusOr<CaseSpec> carried = ParseCase(c->case_json, ".");
  EXPECT_TRUE(carried.ok()) << carried.status();
  if (!carried.ok()) return std::nullopt;
  return *std::move(carried);
}

// `o` with ShortCase(20) stopped after 4 steps in `out` (a checkpoint there).
SimulationOptions StoppedShortRun(const std::string& out) {
  SimulationOptions o = Options(out);
  o.stop_after_steps = 4;
  std::unique_ptr<Simulation> a = StartOrDie(ShortCase(20), o);
  EXPECT_NE(a, nullptr);
  if (a != nullptr) {
    EXPECT_TRUE(a->StepToEnd().ok());
  }
  return o;
}

// A run whose timeseries has other columns than this binary writes (a
// collapse run from before its mass-front columns) is refused at resume with
// a specific error, and none of its files changes: the header is checked
// before the results file is opened (which would mark it resumed).
TEST(SimulationTest, ResumeIntoOtherColumnsIsRefusedAndTouchesNothing) {
  const std::string out = FreshDir("resume_other_columns");
  const SimulationOptions o = StoppedShortRun(out);
  const auto bytes = [&](const std::string& name) {
    std::ifstream in(out + "/" + name, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  std::string csv = bytes("timeseries.csv");
  ASSERT_TRUE(absl::StartsWith(csv, "time,step,"));
  csv.replace(0, 4, "TIME");  // another header
  // A temporary stream: written and closed in this statement.
  std::ofstream(out + "/timeseries.csv", std::ios::binary) << csv;
  const std::vector<std::string> files = {"results.h5", "results.xdmf", "timeseries.csv",
                                          "checkpoint.h5"};
  std::vector<std::string> before;
  for (const std::string& f : files) before.push_back(bytes(f));
  absl::StatusOr<std::unique_ptr<Simulation>> b = Simulation::Resume(out + "/checkpoint.h5", o);
  EXPECT_EQ(b.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_TRUE(absl::StrContains(b.status().message(), "does not have the columns of this case"))
      << b.status();
  for (std::size_t i = 0; i < files.size(); ++i) {
    EXPECT_TRUE(bytes(files[i]) == before[i]) << files[i] << " changed";  // binary: no dump
  }
}

// A run resumed with --f-bar goes on with it, and its later checkpoints carry
// it: a second resume without the option keeps it, one with "none" drops it.
TEST(SimulationTest, ResumeWithFBarCarriesIt) {
  const std::string out = FreshDir("f_bar_resume");
  SimulationOptions o = StoppedShortRun(out);
  for (std::optional<FBar> f_bar :
       {std::optional(FBar::kNodal), std::optional<FBar>(), std::optional(FBar::kNone)}) {
    SCOPED_TRACE(f_bar ? FBarName(*f_bar) : "unset");
    o.f_bar = f_bar;
    const std::optional<CaseSpec> carried = ResumedAndCarried(out, o);
    ASSERT_TRUE(carried.has_value());
    EXPECT_EQ(carried->solver.f_bar, f_bar == FBar::kNone ? FBar::kNone : FBar::kNodal);
  }
}

// Likewise --nonlocal-radius and --nonlocal-fraction (cells of 1 m here): a
// radius the case would refuse is refused at resume.
TEST(SimulationTest, ResumeWithANonlocalStrainCarriesIt) {
  const std::string out = FreshDir("nonlocal_resume");
  SimulationOptions o = StoppedShortRun(out);
  o.nonlocal_radius = 0.01;
  absl::StatusOr<std::unique_ptr<Simulation>> refused =
      Simulation::Resume(out + "/checkpoint.h5", o);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find(
                "/solver/nonlocal_radius: 0.01 m must be 0 (off) or between 0.1 and 8 cells"),
            std::string::npos)
      << refused.status();
  for (std::optional<double> radius :
       {std::optional<double>(1.5), std::optional<double>(), std::optional<double>(0.0)}) {
    SCOPED_TRACE(radius.value_or(-1));
    o.nonlocal_radius = radius;
    o.nonlocal_fraction = radius == 1.5 ? std::optional<double>(0.75) : std::nullopt;
    const std::optional<CaseSpec> carried = ResumedAndCarried(out, o);
    ASSERT_TRUE(carried.has_value());
    EXPECT_EQ(carried->solver.nonlocal_radius, radius.value_or(1.5));
    EXPECT_EQ(carried->solver.nonlocal_fraction, 0.75);  // set once, then carried
  }
}

// solver.time_step_update_every: Δt follows the points' wave speeds. The
// first update (at rest, four identical RVEs) gives the start's step again;
// as the element is loaded the step changes; the run ends at its end time;
// and a run stopped between two updates and resumed repeats the
// uninterrupted one bit for bit.
TEST(SimulationTest, UpdatedTimeStepFollowsTheRvesAndResumesBitIdentically) {
  CaseSpec spec = LoadOrDie("single-element-biaxial");
  spec.solver.time_step_update_every = 10;
  spec.solver.end_time = 0.6;
  spec.output.frame_every = 50;
  spec.output.timeseries_every = 5;
  spec.output.checkpoint_every = 0;
  const std::string out_a = FreshDir("update_a");
  std::unique_ptr<Simulation> a = StartOrDie(spec, Options(out_a));
  ASSERT_NE(a, nullptr);
  const double dt0 = a->solver().dt();
  absl::StatusOr<SimulationSummary> sa = a->StepToEnd();
  ASSERT_TRUE(sa.ok()) << sa.status();
  EXPECT_TRUE(sa->finished);
  EXPECT_GE(sa->final_time, spec.solver.end_time - 1e-9 * a->solver().dt());
  EXPECT_LT(sa->final_time, spec.solver.end_time + a->solver().dt());
  absl::StatusOr<std::map<std::string, std::vector<double>>> ts =
      ReadCsvColumns(out_a + "/timeseries.csv");
  ASSERT_TRUE(ts.ok()) << ts.status();
  ASSERT_TRUE(ts->contains("time_step"));
  const std::vector<double>& dt = ts->at("time_step");
  ASSERT_GT(dt.size(), 3u);
  EXPECT_EQ(ts->at("step")[1], 5);
  EXPECT_NEAR(dt[1], dt0, 1e-12 * dt0);
  const auto [lo, hi] = std::minmax_element(dt.begin(), dt.end());
  EXPECT_GT(*hi / *lo, 1.01) << "the step never changed";
  EXPECT_LT(*hi / *lo, 2.0);

  absl::StatusOr<store::SimCheckpoint> end_a = a->Snapshot();
  absl::StatusOr<store::SimCheckpoint> end_c = StopAndResume(spec, "update_b", 25);
  ASSERT_TRUE(end_a.ok() && end_c.ok());
  ExpectSameSnapshots(*end_a, *end_c);
}

}  // namespace
}  // namespace rvehub::mpm::sim_test
