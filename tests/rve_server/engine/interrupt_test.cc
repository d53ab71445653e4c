// The engine's Interrupt: long loops stop between DEM steps when
// asked; a stopped Apply leaves the RVE bit for bit as it was; an interrupt
// that never stops changes no result; oversized packings and work are
// refused before anything is allocated or stepped.
#include <gtest/gtest.h>

#include "rve_server/engine/element_test.h"
#include "rve_server/engine/prepare.h"
#include "rve_server/engine/rve.h"
#include "tests/support/test_util.h"

namespace rvehub::dem {
namespace {

using testing_util::CreateOrDie;
using testing_util::ExpectIdenticalPackings;
using testing_util::ExpectIdenticalStates;
using testing_util::Prepared;

Eigen::Matrix3d Compress(double e) {
  Eigen::Matrix3d f = Eigen::Matrix3d::Identity();
  f(1, 1) = 1.0 - e;
  return f;
}

// Stops (Cancelled) when asked for the `n`-th time; counts the asks.
struct StopAt {
  int n;
  int asked = 0;
  Interrupt Fn() {
    return [this]() -> absl::Status {
      return ++asked >= n ? absl::CancelledError("stop") : absl::OkStatus();
    };
  }
};

RveSnapshot LongIncrements() {
  RveSnapshot p = Prepared("SET-dense");
  p.controls.min_steps = 2000;  // several interrupt checks per increment
  return p;
}

TEST(InterruptTest, StoppedApplyLeavesTheRveAsItWas) {
  Rve rve = CreateOrDie(LongIncrements());
  ASSERT_TRUE(rve.Apply(Compress(1e-4)).ok());  // a history to keep
  const RveSnapshot before = rve.ToSnapshot();
  StopAt stop{3};
  absl::StatusOr<RveState> s = rve.Apply(Compress(1e-4), {}, stop.Fn());
  ASSERT_EQ(s.status().code(), absl::StatusCode::kCancelled) << s.status();
  EXPECT_EQ(stop.asked, 3);
  ExpectIdenticalPackings(before, rve.ToSnapshot(), "after a stopped Apply");
  // And it continues exactly as an RVE that was never interrupted.
  Rve twin = CreateOrDie(LongIncrements());
  ASSERT_TRUE(twin.Apply(Compress(1e-4)).ok());
  absl::StatusOr<RveState> a = rve.Apply(Compress(1e-4));
  absl::StatusOr<RveState> b = twin.Apply(Compress(1e-4));
  ASSERT_TRUE(a.ok() && b.ok());
  ExpectIdenticalStates(*a, *b, "continuation after a stopped Apply");
  ExpectIdenticalPackings(rve.ToSnapshot(), twin.ToSnapshot(), "continuation");
}

TEST(InterruptTest, StoppedRelaxationUndoesTheWholeIncrement) {
  Rve rve = CreateOrDie(Prepared("SET-dense"));
  const RveSnapshot before = rve.ToSnapshot();
  ApplyOptions options;
  options.relax = true;
  options.relax_tolerance = kMinRelaxTolerance;  // never reached
  options.relax_max_steps = kMaxRelaxSteps;
  StopAt stop{4};
  absl::StatusOr<RveState> s = rve.Apply(Compress(1e-4), options, stop.Fn());
  ASSERT_EQ(s.status().code(), absl::StatusCode::kCancelled) << s.status();
  ExpectIdenticalPackings(before, rve.ToSnapshot(), "after a stopped relaxation");
}

TEST(InterruptTest, AnInterruptThatNeverStopsChangesNoResult) {
  Rve asked = CreateOrDie(LongIncrements());
  Rve plain = CreateOrDie(LongIncrements());
  StopAt never{1 << 30};
  ApplyOptions options;
  options.relax = true;
  for (int k = 0; k < 3; ++k) {
    absl::StatusOr<RveState> a = asked.Apply(Compress(2e-4), options, never.Fn());
    absl::StatusOr<RveState> b = plain.Apply(Compress(2e-4), options);
    ASSERT_TRUE(a.ok() && b.ok());
    ExpectIdenticalStates(*a, *b, "increment " + std::to_string(k));
  }
  EXPECT_GT(never.asked, 0);
  ExpectIdenticalPackings(asked.ToSnapshot(), plain.ToSnapshot(), "after three increments");
}

TEST(InterruptTest, ConsolidationAndElementTestsStopWhenAsked) {
  Rve rve = CreateOrDie(Prepared("SET-dense"));
  StopAt stop{2};
  absl::StatusOr<RveState> c = ConsolidateIsotropic(rve, 400e3, 1e-4, nullptr, stop.Fn());
  EXPECT_EQ(c.status().code(), absl::StatusCode::kCancelled) << c.status();
  Rve fresh = CreateOrDie(Prepared("SET-dense"));
  StopAt later{5};
  ElementTestSpec spec;
  spec.kind = ElementTestKind::kDrainedBiaxial;
  absl::StatusOr<std::vector<ElementTestRow>> rows = RunElementTest(fresh, spec, {}, later.Fn());
  EXPECT_EQ(rows.status().code(), absl::StatusCode::kCancelled) << rows.status();
  EXPECT_EQ(later.asked, 5);
}

TEST(InterruptTest, OutOfRangeWorkIsRefusedBeforeAnyStep) {
  // A loose packing (no contacts: p is the 1 Pa floor), stiff contacts (a
  // tiny time step) and the slowest inertial number: each parameter in
  // range, the increment far beyond kMaxStepsPerApply steps.
  RveSnapshot stiff = Prepared("SET-dense");
  stiff.cell *= 1.5;
  stiff.reference_cell = stiff.cell;
  stiff.contacts.clear();
  stiff.controls.pressure_floor = kMinPressureFloor;
  stiff.material.young_modulus *= 1e6;
  Rve rve = CreateOrDie(stiff);
  const RveSnapshot before = rve.ToSnapshot();
  ApplyOptions slow;
  slow.max_inertial_number = kMinInertialNumber;
  absl::StatusOr<RveState> s = rve.Apply(Compress(0.04), slow);
  EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument) << s.status();
  EXPECT_NE(s.status().message().find("DEM steps"), std::string::npos) << s.status();
  ExpectIdenticalPackings(before, rve.ToSnapshot(), "after a refused increment");

  RveSnapshot huge = Prepared("SET-dense");
  huge.cell *= 1e4;  // 1e8 times the area for the same discs
  absl::Status v = ValidatePacking(huge);
  EXPECT_EQ(v.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(v.message().find("cell is too large"), std::string::npos) << v;
}

}  // namespace
}  // namespace rvehub::dem
