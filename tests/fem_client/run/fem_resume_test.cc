// fem_client's checkpoints and resume (fem_client/run/simulation.h) on an
// embedded server: a run stopped and resumed gives the uninterrupted run's
// timeseries and results frames bit for bit (wall times aside), with
// cut-backs before the checkpoint (the RVEs' committed step ahead of the
// load steps) and with a forced platen; output.checkpoint_every writes
// them; a resume may change the Newton settings and nothing else; a
// checkpoint that is not one, or whose state does not fit its case, is
// refused before anything is written.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "client_run/timeseries.h"
#include "fem_client/case/case.h"
#include "fem_client/run/simulation.h"
#include "store/results.h"
#include "store/sim_checkpoint.h"
#include "tests/fem_client/run/fem_run_test_util.h"

namespace rvehub::fem {
namespace {

namespace fs = std::filesystem;
using run_test::Columns;
using run_test::ReadColumns;

std::string Scratch(const std::string& name) {
  return run_test::ScratchPath("fem_resume_test", name);
}

FemSimulationOptions Options(const std::string& out, std::int64_t stop_after = 0) {
  FemSimulationOptions o;
  o.out_dir = out;
  o.threads = 2;
  o.template_cache_dir = (fs::path(testing::TempDir()) / "fem_test_templates").string();
  o.stop_after_steps = stop_after;
  o.progress = false;
  o.log = [](const std::string&) {};
  return o;
}

FemCase Load(const std::string& name, std::vector<CaseOverride> overrides = {}) {
  absl::StatusOr<FemCase> c =
      LoadFemCase(std::string(RVEHUB_SOURCE_DIR "/cases/") + name + ".json", overrides);
  EXPECT_TRUE(c.ok()) << c.status();
  return c.ok() ? *c : FemCase{};
}

absl::StatusOr<FemRunSummary> RunCase(const FemCase& c, const FemSimulationOptions& o) {
  absl::StatusOr<std::unique_ptr<FemSimulation>> sim = FemSimulation::Start(c, o);
  if (!sim.ok()) return sim.status();
  return (*sim)->StepToEnd();
}

absl::StatusOr<FemRunSummary> ResumeCase(const std::string& checkpoint,
                                         const FemSimulationOptions& o) {
  absl::StatusOr<std::unique_ptr<FemSimulation>> sim = FemSimulation::Resume(checkpoint, o);
  if (!sim.ok()) return sim.status();
  return (*sim)->StepToEnd();
}

bool SameBits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), sizeof(double) * a.size()) == 0;
}

// Two runs' outputs (timeseries, Newton iterations, results frames), bit
// for bit but for the wall time per step.
void ExpectSameOutputs(const std::string& a, const std::string& b) {
  const Columns ta = ReadColumns(a + "/timeseries.csv"), tb = ReadColumns(b + "/timeseries.csv");
  ASSERT_EQ(ta.size(), tb.size());
  for (const auto& [name, values] : ta) {
    if (name == "wall_step_s") continue;
    EXPECT_TRUE(SameBits(values, tb.at(name))) << name;
  }
  const Columns ia = ReadColumns(a + "/iterations.csv"), ib = ReadColumns(b + "/iterations.csv");
  ASSERT_EQ(ia.size(), 6u);
  for (const auto& [name, values] : ia) EXPECT_TRUE(SameBits(values, ib.at(name))) << name;
  absl::StatusOr<std::vector<store::ResultFrame>> fa = store::ReadResults(a + "/results.h5");
  absl::StatusOr<std::vector<store::ResultFrame>> fb = store::ReadResults(b + "/results.h5");
  ASSERT_TRUE(fa.ok()) << fa.status();
  ASSERT_TRUE(fb.ok()) << fb.status();
  ASSERT_EQ(fa->size(), fb->size());
  for (std::size_t k = 0; k < fa->size(); ++k) {
    SCOPED_TRACE(absl::StrCat("frame ", k));
    EXPECT_EQ((*fa)[k].step, (*fb)[k].step);
    EXPECT_TRUE(SameBits((*fa)[k].position, (*fb)[k].position));
    ASSERT_EQ((*fa)[k].fields.size(), (*fb)[k].fields.size());
    for (std::size_t f = 0; f < (*fa)[k].fields.size(); ++f) {
      EXPECT_EQ((*fa)[k].fields[f].name, (*fb)[k].fields[f].name);
      EXPECT_TRUE(SameBits((*fa)[k].fields[f].values, (*fb)[k].fields[f].values))
          << (*fa)[k].fields[f].name;
    }
  }
}

// The coarse biaxial specimen in seven steps of 0.2 % with at most six
// Newton iterations: steps 5 and 7 need cut-backs (measured: 1 and 4), so a
// checkpoint after step 6 holds RVEs committed 7 times and the predictor's
// last increment comes from a cut-back part of a step. Stopped there
// (with checkpoints every 2 steps on) and resumed, the run ends as the
// uninterrupted one.
TEST(FemResumeTest, AStoppedAndResumedRunIsTheUninterruptedRun) {
  const FemCase c = Load("fem-biaxial-coarse-ci", {{"/solver/max_iterations", "6"},
                                                   {"/loading/steps", "7"},
                                                   {"/loading/end_axial_strain", "0.014"},
                                                   {"/output/checkpoint_every", "2"}});
  const std::string full = Scratch("full"), part = Scratch("part");
  absl::StatusOr<FemRunSummary> a = RunCase(c, Options(full));
  ASSERT_TRUE(a.ok()) << a.status();
  EXPECT_TRUE(a->finished);
  const Columns ts = ReadColumns(full + "/timeseries.csv");
  ASSERT_EQ(ts.at("cutbacks").size(), 8u);
  EXPECT_GT(ts.at("cutbacks")[5] + ts.at("cutbacks")[6], 0) << "no cut-back before the stop";
  // Checkpoints on: the last one is at the end.
  absl::StatusOr<store::SimCheckpoint> last = store::ReadSimCheckpoint(full + "/checkpoint.h5");
  ASSERT_TRUE(last.ok()) << last.status();
  EXPECT_EQ(last->step, 7);

  absl::StatusOr<FemRunSummary> stopped = RunCase(c, Options(part, /*stop_after=*/6));
  ASSERT_TRUE(stopped.ok()) << stopped.status();
  EXPECT_FALSE(stopped->finished);
  absl::StatusOr<store::SimCheckpoint> at = store::ReadSimCheckpoint(part + "/checkpoint.h5");
  ASSERT_TRUE(at.ok()) << at.status();
  EXPECT_EQ(at->step, 6);
  EXPECT_GT(at->ints.at("committed_step")[0], 6);
  absl::StatusOr<FemRunSummary> resumed = ResumeCase(part + "/checkpoint.h5", Options(part));
  ASSERT_TRUE(resumed.ok()) << resumed.status();
  EXPECT_TRUE(resumed->finished);
  EXPECT_EQ(resumed->steps, 1);
  ExpectSameOutputs(full, part);
  EXPECT_TRUE(fs::exists(part + "/summary.json"));
}

// The stress-controlled cycle (a forced platen, whose load the checkpoint
// carries), stopped halfway and resumed: its outputs are the uninterrupted
// run's.
TEST(FemResumeTest, AForcedPlatenResumesWithItsLoad) {
  const FemCase c = Load("fem-simple-shear-stress-ci");
  const std::string full = Scratch("shear-full"), part = Scratch("shear-part");
  ASSERT_TRUE(RunCase(c, Options(full)).ok());
  ASSERT_TRUE(RunCase(c, Options(part, /*stop_after=*/4)).ok());
  ASSERT_TRUE(ResumeCase(part + "/checkpoint.h5", Options(part)).ok());
  ExpectSameOutputs(full, part);
}

// With the local second gradient the checkpoint carries its double
// stresses, multipliers and micro-kinematic field: stopped and resumed, the
// reduced case ends as the uninterrupted run.
TEST(FemResumeTest, ASecondGradientResumesWithItsFields) {
  const FemCase c = Load("fem-biaxial-second-gradient-ci");
  const std::string full = Scratch("sg-full"), part = Scratch("sg-part");
  ASSERT_TRUE(RunCase(c, Options(full)).ok());
  ASSERT_TRUE(RunCase(c, Options(part, /*stop_after=*/3)).ok());
  absl::StatusOr<store::SimCheckpoint> at = store::ReadSimCheckpoint(part + "/checkpoint.h5");
  ASSERT_TRUE(at.ok()) << at.status();
  EXPECT_EQ(at->doubles.at("multiplier").size(), 4u * 8);
  EXPECT_EQ(at->doubles.at("double_stress").size(), 8u * 32);
  ASSERT_TRUE(ResumeCase(part + "/checkpoint.h5", Options(part)).ok());
  ExpectSameOutputs(full, part);
}

// A resume may change the Newton settings from its step on: a tolerance ten
// times tighter here, which every later step meets, and which the
// checkpoints written after carry. Any other field of the case, or a value
// the case reader refuses, is refused by its pointer before anything is
// written.
TEST(FemResumeTest, AResumeMayChangeTheNewtonSettingsOnly) {
  const FemCase c = Load("fem-single-element-ci", {{"/output/checkpoint_every", "1"}});
  ASSERT_EQ(c.solver.tolerance, 0.01);
  const std::string part = Scratch("tighter");
  ASSERT_TRUE(RunCase(c, Options(part, /*stop_after=*/2)).ok());
  const std::vector<CaseOverride> tighter = {{"/solver/tolerance", "1e-3"},
                                             {"/solver/max_iterations", "60"}};
  absl::StatusOr<std::unique_ptr<FemSimulation>> sim =
      FemSimulation::Resume(part + "/checkpoint.h5", Options(part), tighter);
  ASSERT_TRUE(sim.ok()) << sim.status();
  EXPECT_EQ((*sim)->spec().solver.tolerance, 1e-3);
  ASSERT_TRUE((*sim)->StepToEnd().ok());
  const std::vector<double>& error_d = ReadColumns(part + "/timeseries.csv").at("error_d");
  ASSERT_EQ(error_d.size(), 6u);  // row 0 and five steps
  for (std::size_t step = 3; step <= 5; ++step) EXPECT_LT(error_d[step], 1e-3) << step;
  absl::StatusOr<store::SimCheckpoint> end = store::ReadSimCheckpoint(part + "/checkpoint.h5");
  ASSERT_TRUE(end.ok()) << end.status();
  EXPECT_EQ(end->step, 5);
  absl::StatusOr<FemCase> written = ParseFemCase(end->case_json, ".");
  ASSERT_TRUE(written.ok()) << written.status();
  EXPECT_EQ(written->solver.tolerance, 1e-3);
  EXPECT_EQ(written->solver.max_iterations, 60);

  // From the perturbation tangent back to the contact one: its ξ goes.
  const std::string perturbed = Scratch("perturbed");
  ASSERT_TRUE(
      RunCase(Load("fem-single-element-ci", {{"/solver", R"({"tangent": "perturbation"})"}}),
              Options(perturbed, /*stop_after=*/2))
          .ok());
  const std::vector<CaseOverride> contact = {{"/solver/tangent", "\"contact\""}};
  sim = FemSimulation::Resume(perturbed + "/checkpoint.h5", Options(perturbed), contact);
  ASSERT_TRUE(sim.ok()) << sim.status();
  EXPECT_EQ((*sim)->spec().solver.tangent, TangentKind::kContact);

  const std::string out = Scratch("not-resumed");
  const std::pair<CaseOverride, const char*> refused[] = {
      {{"/mesh/elements/0", "2"},
       "--set /mesh/elements/0: a resume may change only the Newton settings"},
      {{"/solver/second_gradient_N", "5"},
       "--set /solver/second_gradient_N: a resume may change only the Newton settings"},
      {{"/solver/tolerance", "5"}, "/solver/tolerance"},
  };
  for (const auto& [o, message] : refused) {
    SCOPED_TRACE(o.pointer);
    const std::vector<CaseOverride> one = {o};
    absl::StatusOr<std::unique_ptr<FemSimulation>> bad =
        FemSimulation::Resume(part + "/checkpoint.h5", Options(out), one);
    EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument) << bad.status();
    EXPECT_TRUE(absl::StrContains(bad.status().message(), message)) << bad.status();
    EXPECT_FALSE(fs::exists(out));
  }
}

// What Resume refuses, before it writes anything.
TEST(FemResumeTest, ACheckpointThatIsNotOneIsRefused) {
  const std::string out = Scratch("refused");
  absl::StatusOr<std::unique_ptr<FemSimulation>> missing =
      FemSimulation::Resume(Scratch("none") + "/checkpoint.h5", Options(out));
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kNotFound) << missing.status();

  // A real checkpoint, then spoilt copies of it.
  const FemCase c = Load("fem-single-element-ci");
  const std::string source = Scratch("source");
  ASSERT_TRUE(RunCase(c, Options(source, /*stop_after=*/2)).ok());
  absl::StatusOr<store::SimCheckpoint> good = store::ReadSimCheckpoint(source + "/checkpoint.h5");
  ASSERT_TRUE(good.ok()) << good.status();
  struct Bad {
    const char* name;
    void (*spoil)(store::SimCheckpoint&);
    const char* message;
  };
  const Bad cases[] = {
      {"another client's case",
       [](store::SimCheckpoint& s) { s.case_json = R"({"name": "x", "grid": {}})"; },
       "its case does not parse"},
      {"a state key missing", [](store::SimCheckpoint& s) { s.doubles.erase("nodes"); },
       "'nodes' is missing"},
      {"a stress short", [](store::SimCheckpoint& s) { s.doubles.at("stress").resize(27); },
       "'has_tangent' holds 4 Gauss points, not 3"},
      {"a position not finite",
       [](store::SimCheckpoint& s) { s.doubles.at("nodes")[2] = std::nan(""); },
       "nodes has a position that is not finite"},
      {"a negative step count", [](store::SimCheckpoint& s) { s.ints.at("steps")[0] = -4; },
       "'steps' is -4"},
      {"RVEs for another mesh", [](store::SimCheckpoint& s) { s.rves.pop_back(); },
       "holds 3 RVEs for a mesh of 4 Gauss points"},
  };
  for (const Bad& bad : cases) {
    SCOPED_TRACE(bad.name);
    store::SimCheckpoint spoilt = *good;
    bad.spoil(spoilt);
    const std::string path = Scratch("spoilt") + ".h5";
    ASSERT_TRUE(store::WriteSimCheckpoint(path, spoilt, store::FileInfo{}).ok());
    absl::StatusOr<std::unique_ptr<FemSimulation>> sim = FemSimulation::Resume(path, Options(out));
    EXPECT_EQ(sim.status().code(), absl::StatusCode::kDataLoss) << sim.status();
    EXPECT_TRUE(absl::StrContains(sim.status().message(), bad.message)) << sim.status();
    EXPECT_TRUE(absl::StartsWith(sim.status().message(), path)) << sim.status();
    EXPECT_FALSE(fs::exists(out));
  }
}

}  // namespace
}  // namespace rvehub::fem
