// Input validation of the DEM engine: every bad input is refused with a
// specific status code and a message naming the problem, and a refused call
// leaves the RVE bit-for-bit untouched. Also: an RVE without contacts reports
// a well-defined (zero, NaN-free) state.
#include <Eigen/Dense>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <numbers>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/match.h"
#include "absl/strings/string_view.h"
#include "gtest/gtest-spi.h"
#include "gtest/gtest.h"
#include "rve_server/engine/element_test.h"
#include "rve_server/engine/prepare.h"
#include "rve_server/engine/rve.h"
#include "rve_server/values/material.h"
#include "rve_server/values/snapshot.h"
#include "tests/support/test_util.h"

namespace rvehub::dem {
namespace {

// gmock is not linked: a plain substring predicate for messages.
testing::AssertionResult HasSubstr(absl::string_view text, absl::string_view part) {
  if (absl::StrContains(text, part)) return testing::AssertionSuccess();
  return testing::AssertionFailure() << "\"" << text << "\" does not contain \"" << part << "\"";
}

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

using testing_util::CreateOrDie;
using testing_util::ExpectIdenticalPackings;
using testing_util::SquareLattice;

// --- A small, loaded RVE with a non-trivial history. ---

// 5×5 square lattice of 5 mm discs at spacing 2r·0.999 (each disc touches
// four neighbours), with rolling resistance, sheared and rotated a little so
// that every part of the state (ft, M_r, frame, velocities, steps) is set.
const RveSnapshot& Loaded() {
  static const RveSnapshot* packing = [] {
    constexpr int kSide = 5;
    constexpr double kR = 5e-3, kSpacing = 2 * kR * 0.999;
    RveSnapshot p = SquareLattice(kSide, kSpacing, [](int x, int y) {
      return kR * (1.0 + 0.001 * ((x + 2 * y) % 3));  // slightly polydisperse
    });
    p.material.name = "validation";
    p.material.rolling_beta = 1.0;
    p.material.rolling_eta = 0.05;
    p.reference_cell = p.cell;
    p.initial_void_ratio = 0.3;
    p.permeability_coefficient = 0.01;
    Rve rve = CreateOrDie(std::move(p));
    CellControl shear;
    shear.xy = {ControlMode::kStrainRate, 2e-5 / rve.time_step()};
    rve.Run(shear, 30);
    Eigen::Matrix3d turn = Eigen::Matrix3d::Identity();
    turn.topLeftCorner<2, 2>() << std::cos(0.1), -std::sin(0.1), std::sin(0.1), std::cos(0.1);
    EXPECT_TRUE(rve.Apply(turn).ok());
    return new RveSnapshot(rve.ToSnapshot());
  }();
  return *packing;
}

TEST(LoadedPackingTest, HasAFullHistory) {
  const RveSnapshot& p = Loaded();
  EXPECT_GE(p.contacts.size(), 40u);
  bool ft = false, moment = false;
  for (const ContactHistory& c : p.contacts) {
    ft |= c.tangential_force != 0.0;
    moment |= c.rolling_moment != 0.0;
  }
  EXPECT_TRUE(ft);
  EXPECT_TRUE(moment);
  EXPECT_NE(p.frame, Eigen::Matrix2d::Identity());
  EXPECT_GT(p.total_steps, 0);
}

// The comparison itself can fail: a one-ulp change anywhere is reported.
TEST(LoadedPackingTest, ExpectIdenticalSeesAOneUlpChange) {
  RveSnapshot p = Loaded();
  p.sx[3] = std::nextafter(p.sx[3], 2.0);
  EXPECT_NONFATAL_FAILURE(ExpectIdenticalPackings(p, Loaded()), "sx[3]");
  RveSnapshot q = Loaded();
  q.contacts[2].tangential_force = std::nextafter(q.contacts[2].tangential_force, 1e9);
  EXPECT_NONFATAL_FAILURE(ExpectIdenticalPackings(q, Loaded()), "contact 2");
  RveSnapshot r = Loaded();
  r.frame(0, 1) = std::nextafter(r.frame(0, 1), 1.0);
  EXPECT_NONFATAL_FAILURE(ExpectIdenticalPackings(r, Loaded()), "frame");
}

// --- Apply. ---

struct ApplyCase {
  std::string name;
  Eigen::Matrix3d delta_f;
  std::string message;  // a substring the message must contain
};

Eigen::Matrix3d Diag(double xx, double yy, double zz = 1.0) {
  return Eigen::Vector3d(xx, yy, zz).asDiagonal();
}

Eigen::Matrix3d With(Eigen::Matrix3d m, int r, int c, double v) {
  m(r, c) = v;
  return m;
}

Eigen::Matrix3d Rotation(double angle) {
  Eigen::Matrix3d m = Eigen::Matrix3d::Identity();
  m.topLeftCorner<2, 2>() << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle);
  return m;
}

std::vector<ApplyCase> BadApplyCases() {
  const Eigen::Matrix3d id = Eigen::Matrix3d::Identity();
  return {
      {"nan_xx", With(id, 0, 0, kNaN), "ΔF(0,0)"},
      {"inf_yx", With(id, 1, 0, kInf), "ΔF(1,0)"},
      {"minus_inf_xy", With(id, 0, 1, -kInf), "ΔF(0,1)"},
      {"nan_zz", With(id, 2, 2, kNaN), "ΔF(2,2)"},
      {"reflection", Diag(-1.0, 1.0), "det ΔF"},
      {"singular", Diag(1.0, 0.0), "det ΔF"},
      {"point_inversion", Diag(-1.0, -1.0), "rotation"},   // det > 0: a rotation by π
      {"stretch", Diag(1.06, 1.0), "stretch"},             // |V − I| = 0.06 > 0.05
      {"shear_stretch", With(id, 0, 1, 0.11), "stretch"},  // |V − I| ≈ 0.078
      {"rotation", Rotation(0.6), "rotation"},             // > max_rotation 0.5 rad
      {"out_of_plane_zz", Diag(1.0, 1.0, 1.01), "plane strain"},
      {"out_of_plane_xz", With(id, 0, 2, 0.01), "plane strain"},
      {"out_of_plane_zy", With(id, 2, 1, 0.01), "plane strain"},
  };
}

void PrintTo(const ApplyCase& c, std::ostream* os) { *os << c.name; }

class BadApplyTest : public testing::TestWithParam<ApplyCase> {};

TEST_P(BadApplyTest, RefusedWithInvalidArgumentAndNoChange) {
  const ApplyCase& c = GetParam();
  Rve rve = CreateOrDie(Loaded());
  Rve twin = CreateOrDie(Loaded());
  const absl::StatusOr<RveState> s = rve.Apply(c.delta_f);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument) << s.status();
  EXPECT_TRUE(HasSubstr(s.status().message(), c.message));
  ExpectIdenticalPackings(rve.ToSnapshot(), Loaded());
  // Nothing hidden changed either: both continue identically.
  CellControl shear;
  shear.xy = {ControlMode::kStrainRate, 1e-5 / rve.time_step()};
  rve.Run(shear, 20);
  twin.Run(shear, 20);
  ExpectIdenticalPackings(rve.ToSnapshot(), twin.ToSnapshot());
}

INSTANTIATE_TEST_SUITE_P(Cases, BadApplyTest, testing::ValuesIn(BadApplyCases()),
                         [](const testing::TestParamInfo<ApplyCase>& info) {
                           return info.param.name;
                         });

TEST(ApplyTest, ValidIncrementsAreAccepted) {
  // Positive control for the cases above: just inside each limit.
  Rve rve = CreateOrDie(Loaded());
  EXPECT_TRUE(rve.Apply(Diag(1.049, 1.0)).ok());
  EXPECT_TRUE(rve.Apply(Rotation(0.49)).ok());
  EXPECT_TRUE(rve.Apply(With(Eigen::Matrix3d::Identity(), 2, 2, 1.0 + 1e-13)).ok());
}

// duration caps the DEM steps at ⌈duration/Δt⌉ where the quasi-static bound
// asks for more, and never goes below min_steps; out of range it is refused.
TEST(ApplyTest, DurationCapsTheDemSteps) {
  RveSnapshot p = Loaded();
  p.controls.min_steps = 3;
  Rve rve = CreateOrDie(p);
  Rve twin = CreateOrDie(p);
  const Eigen::Matrix3d df = Diag(0.99, 1.0);
  absl::StatusOr<RveState> free = twin.Apply(df);
  ASSERT_TRUE(free.ok()) << free.status();
  ASSERT_GT(free->steps, 20);  // the quasi-static bound asks for many
  ApplyOptions capped;
  capped.duration = 7.5 * rve.time_step();
  absl::StatusOr<RveState> s = rve.Apply(df, capped);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->steps, 8);
  capped.duration = 0.5 * rve.time_step();
  s = rve.Apply(df, capped);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->steps, 3);  // min_steps
  capped.duration = 1.0;   // longer than the bound needs: no effect
  Rve third = CreateOrDie(p);
  s = third.Apply(df, capped);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->steps, free->steps);
  for (double bad : {-1e-9, 2e6, std::nan("")}) {
    capped.duration = bad;
    s = rve.Apply(df, capped);
    ASSERT_FALSE(s.ok()) << bad;
    EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_TRUE(HasSubstr(s.status().message(), "duration")) << s.status();
  }
}

// A thin cell is doubled (periodic_test.cc), at most twice per increment:
// a cell still too thin after that is refused.
TEST(ApplyTest, CellThinnerThanTheCutoffEvenDoubledIsAFailedPrecondition) {
  RveSnapshot p = Loaded();
  p.controls.max_stretch = 2.0;  // let the stretch limit pass
  Rve rve = CreateOrDie(p);
  const RveSnapshot before = rve.ToSnapshot();
  // The 5×5 cell is ~10 radii wide; 0.4 of it is below 2 × (2 r_max + skin·r_min),
  // and so is 4 × 0.1 of it.
  const absl::StatusOr<RveState> s = rve.Apply(Diag(0.1, 1.0));
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), absl::StatusCode::kFailedPrecondition) << s.status();
  EXPECT_TRUE(HasSubstr(s.status().message(), "cutoff"));
  ExpectIdenticalPackings(rve.ToSnapshot(), before);
}

// ΔF whose volume change would leave e ≤ 0 (the cell's area below the
// discs' own) is refused before anything moves: e after ΔF is geometry
// alone. Just above that it runs.
TEST(ApplyTest, SqueezingTheCellBelowTheDiscsAreaIsRefused) {
  RveSnapshot p = Loaded();
  p.controls.max_stretch = 2.0;  // let the stretch limit pass
  Rve rve = CreateOrDie(p);
  const RveSnapshot before = rve.ToSnapshot();
  const double e = rve.Observe().void_ratio;
  ASSERT_GT(e, 0.0);
  const double to_zero = 1.0 / (1.0 + e);  // det ΔF that makes e = 0
  const absl::StatusOr<RveState> s = rve.Apply(Diag(to_zero * 0.999, 1.0));
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument) << s.status();
  EXPECT_TRUE(HasSubstr(s.status().message(), "would squeeze the cell below the discs' own area"))
      << s.status();
  ExpectIdenticalPackings(rve.ToSnapshot(), before);
  EXPECT_TRUE(rve.Apply(Diag(1.0 - 0.5 * (1.0 - to_zero), 1.0)).ok());
}

// --- Create. ---

struct CreateCase {
  std::string name;
  std::function<void(RveSnapshot&)> corrupt;
  std::string message;
};

std::vector<CreateCase> BadCreateCases() {
  std::vector<CreateCase> cases;
  using Field = std::vector<double> RveSnapshot::*;
  for (const auto& [name, field] : {std::pair<const char*, Field>{"sx", &RveSnapshot::sx},
                                    {"sy", &RveSnapshot::sy},
                                    {"vx", &RveSnapshot::vx},
                                    {"vy", &RveSnapshot::vy},
                                    {"omega", &RveSnapshot::omega},
                                    {"theta", &RveSnapshot::theta}}) {
    const std::string n = name;
    const Field f = field;
    cases.push_back({"short_" + n, [f](RveSnapshot& p) { (p.*f).pop_back(); },
                     "field " + n + " has 24 entries"});
    cases.push_back({"long_" + n, [f](RveSnapshot& p) { (p.*f).push_back(0.0); },
                     "field " + n + " has 26 entries"});
    cases.push_back({"nan_" + n, [f](RveSnapshot& p) { (p.*f)[7] = kNaN; }, n + "[7]"});
    cases.push_back({"inf_" + n, [f](RveSnapshot& p) { (p.*f)[3] = -kInf; }, n + "[3]"});
  }
  cases.push_back({"zero_radius", [](RveSnapshot& p) { p.radius[4] = 0.0; }, "radius[4]"});
  cases.push_back({"negative_radius", [](RveSnapshot& p) { p.radius[2] = -1e-3; }, "radius[2]"});
  cases.push_back({"nan_radius", [](RveSnapshot& p) { p.radius[1] = kNaN; }, "radius[1]"});
  cases.push_back({"inf_radius", [](RveSnapshot& p) { p.radius[0] = kInf; }, "radius[0]"});
  cases.push_back({"one_particle",
                   [](RveSnapshot& p) {
                     for (auto* v : {&p.radius, &p.sx, &p.sy, &p.vx, &p.vy, &p.omega, &p.theta}) {
                       v->resize(1);
                     }
                     p.contacts.clear();
                   },
                   "1 particles"});
  cases.push_back(
      {"negative_det_cell", [](RveSnapshot& p) { p.cell.col(0).swap(p.cell.col(1)); }, "det"});
  cases.push_back({"singular_cell", [](RveSnapshot& p) { p.cell.col(1) = p.cell.col(0); }, "det"});
  cases.push_back({"nan_cell", [](RveSnapshot& p) { p.cell(1, 0) = kNaN; }, "cell matrix"});
  cases.push_back({"cell_too_small", [](RveSnapshot& p) { p.cell *= 0.4; }, "too small"});
  cases.push_back({"nan_reference_cell", [](RveSnapshot& p) { p.reference_cell(0, 1) = kNaN; },
                   "reference_cell"});
  cases.push_back({"singular_reference_cell",
                   [](RveSnapshot& p) { p.reference_cell.col(0).setZero(); }, "reference_cell"});
  cases.push_back({"frame_not_rotation", [](RveSnapshot& p) { p.frame *= 2.0; }, "frame"});
  cases.push_back({"frame_reflection", [](RveSnapshot& p) { p.frame.col(0) *= -1.0; }, "frame"});
  cases.push_back({"contacts_unsorted",
                   [](RveSnapshot& p) { std::swap(p.contacts[3], p.contacts[4]); }, "sorted"});
  cases.push_back({"contacts_duplicate",
                   [](RveSnapshot& p) { p.contacts.insert(p.contacts.begin() + 2, p.contacts[2]); },
                   "without repeats"});
  cases.push_back({"contact_j_out_of_range",
                   [](RveSnapshot& p) {
                     p.contacts.push_back({3, 25, 0.1, 0.0, 0.0});
                   },
                   "need i < j"});
  cases.push_back({"contact_i_equals_j",
                   [](RveSnapshot& p) {
                     p.contacts.back() = {24, 24, 0.1, 0.0, 0.0};
                   },
                   "need i < j"});
  cases.push_back({"contact_i_above_j",
                   [](RveSnapshot& p) { std::swap(p.contacts[0].i, p.contacts[0].j); },
                   "need i < j"});
  cases.push_back({"contact_nan_ft", [](RveSnapshot& p) { p.contacts[5].tangential_force = kNaN; },
                   "contact 5"});
  cases.push_back({"contact_inf_moment",
                   [](RveSnapshot& p) { p.contacts[6].rolling_moment = kInf; }, "contact 6"});
  cases.push_back({"contact_negative_bond",
                   [](RveSnapshot& p) { p.contacts[1].bond_strength = -1.0; }, "contact 1"});
  cases.push_back({"bad_material", [](RveSnapshot& p) { p.material.density = 0.0; }, "density"});
  cases.push_back({"bad_controls", [](RveSnapshot& p) { p.controls.skin = 0.0; }, "skin"});
  cases.push_back({"hertz_with_bonds",
                   [](RveSnapshot& p) {
                     p.material.model = ContactModel::kHertzMindlin;
                     p.material.bond_cohesion = 1e6;
                   },
                   "linear contact model"});
  cases.push_back({"nan_void_ratio", [](RveSnapshot& p) { p.initial_void_ratio = kNaN; },
                   "initial_void_ratio"});
  cases.push_back({"negative_permeability",
                   [](RveSnapshot& p) { p.permeability_coefficient = -1.0; },
                   "permeability_coefficient"});
  return cases;
}

void PrintTo(const CreateCase& c, std::ostream* os) { *os << c.name; }

class BadCreateTest : public testing::TestWithParam<CreateCase> {};

TEST_P(BadCreateTest, RefusedWithInvalidArgument) {
  RveSnapshot p = Loaded();
  ASSERT_TRUE(Rve::Create(p).ok());  // the unmodified packing is valid
  ASSERT_GE(p.contacts.size(), 7u);
  GetParam().corrupt(p);
  const absl::StatusOr<Rve> rve = Rve::Create(p);
  ASSERT_FALSE(rve.ok());
  EXPECT_EQ(rve.status().code(), absl::StatusCode::kInvalidArgument) << rve.status();
  EXPECT_TRUE(HasSubstr(rve.status().message(), GetParam().message));
}

INSTANTIATE_TEST_SUITE_P(Cases, BadCreateTest, testing::ValuesIn(BadCreateCases()),
                         [](const testing::TestParamInfo<CreateCase>& info) {
                           return info.param.name;
                         });

// Two discs at the same centre have no contact normal (n = 0/0): Create
// refuses them, naming the particles.
TEST(CreateTest, CoincidentCentresAreRefused) {
  RveSnapshot p;
  p.cell = Eigen::Matrix2d::Identity() * 0.1;
  p.radius = {5e-3, 5e-3, 5e-3};
  p.sx = {0.5, 0.5, 0.2};
  p.sy = {0.5, 0.5, 0.2};
  p.vx = p.vy = p.omega = p.theta = {0.0, 0.0, 0.0};
  absl::StatusOr<Rve> rve = Rve::Create(p);
  ASSERT_FALSE(rve.ok());
  EXPECT_EQ(rve.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(HasSubstr(rve.status().message(), "particles 0 and 1 have coincident centres"));
}

// --- Validate(Material), Validate(Controls), Validate(PreparationSpec). ---

template <typename T>
struct FieldCase {
  std::string field;
  std::function<void(T&)> corrupt;
};

template <typename T>
void ExpectEachRefused(const std::vector<FieldCase<T>>& cases) {
  ASSERT_TRUE(Validate(T{}).ok()) << "defaults must be valid";
  for (const FieldCase<T>& c : cases) {
    T value;
    c.corrupt(value);
    const absl::Status s = Validate(value);
    EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument) << c.field << ": " << s;
    EXPECT_TRUE(HasSubstr(s.message(), c.field + " = ")) << s;
  }
}

TEST(ValidateTest, MaterialRefusesEachBadField) {
  ExpectEachRefused<Material>({
      {"density", [](Material& m) { m.density = 0.0; }},
      {"density", [](Material& m) { m.density = kNaN; }},
      {"young_modulus", [](Material& m) { m.young_modulus = -1.0; }},
      {"young_modulus", [](Material& m) { m.young_modulus = kInf; }},
      {"stiffness_ratio", [](Material& m) { m.stiffness_ratio = -0.1; }},
      {"poisson_ratio", [](Material& m) { m.poisson_ratio = 0.5; }},
      {"poisson_ratio", [](Material& m) { m.poisson_ratio = -1.0; }},
      {"friction", [](Material& m) { m.friction = -0.01; }},
      {"friction", [](Material& m) { m.friction = kNaN; }},
      {"rolling_beta", [](Material& m) { m.rolling_beta = -1.0; }},
      {"rolling_eta", [](Material& m) { m.rolling_eta = -1.0; }},
      {"bond_cohesion", [](Material& m) { m.bond_cohesion = -1.0; }},
      {"damping", [](Material& m) { m.damping = 1.0; }},
      {"damping", [](Material& m) { m.damping = -0.1; }},
      {"thickness", [](Material& m) { m.thickness = 0.0; }},
  });
  for (const std::string& name : ParameterSetNames()) {
    absl::StatusOr<ParameterSet> set = FindParameterSet(name);
    ASSERT_TRUE(set.ok()) << name;
    EXPECT_TRUE(Validate(set->material).ok()) << name;
    EXPECT_TRUE(Validate(set->preparation).ok()) << name;
  }
}

TEST(ValidateTest, ControlsRefusesEachBadField) {
  ExpectEachRefused<Controls>({
      {"time_step_factor", [](Controls& c) { c.time_step_factor = 0.0; }},
      {"time_step_factor", [](Controls& c) { c.time_step_factor = 1.5; }},
      {"time_step_factor", [](Controls& c) { c.time_step_factor = kNaN; }},
      {"max_inertial_number", [](Controls& c) { c.max_inertial_number = 0.0; }},
      {"pressure_floor", [](Controls& c) { c.pressure_floor = -1.0; }},
      {"min_steps", [](Controls& c) { c.min_steps = -1; }},
      {"max_stretch", [](Controls& c) { c.max_stretch = 0.0; }},
      {"max_stretch", [](Controls& c) { c.max_stretch = kInf; }},
      {"max_rotation", [](Controls& c) { c.max_rotation = 0.0; }},
      {"max_rotation", [](Controls& c) { c.max_rotation = 2.0; }},  // > π/2
      {"mass_scale", [](Controls& c) { c.mass_scale = 0.5; }},
      {"skin", [](Controls& c) { c.skin = 0.0; }},
      {"skin", [](Controls& c) { c.skin = 2.5; }},
  });
}

std::vector<FieldCase<PreparationSpec>> BadPreparationCases() {
  return {
      {"num_particles", [](PreparationSpec& p) { p.num_particles = 1; }},
      {"num_particles", [](PreparationSpec& p) { p.num_particles = 2000000; }},
      {"radius_min", [](PreparationSpec& p) { p.radius_min = 0.0; }},
      {"radius_max", [](PreparationSpec& p) { p.radius_max = 0.5 * p.radius_min; }},
      {"pressure", [](PreparationSpec& p) { p.pressure = 0.0; }},
      {"pressure", [](PreparationSpec& p) { p.pressure = kNaN; }},
      {"target_void_ratio", [](PreparationSpec& p) { p.target_void_ratio = 10.0; }},
      {"initial_permeability", [](PreparationSpec& p) { p.initial_permeability = 0.0; }},
  };
}

TEST(ValidateTest, PreparationSpecRefusesEachBadField) {
  ExpectEachRefused<PreparationSpec>(BadPreparationCases());
}

TEST(PreparePackingTest, BadInputsAreRefusedBeforeAnyWork) {
  absl::StatusOr<ParameterSet> base = FindParameterSet("SET-dense");
  ASSERT_TRUE(base.ok());
  for (const FieldCase<PreparationSpec>& c : BadPreparationCases()) {
    ParameterSet set = *base;
    c.corrupt(set.preparation);
    const absl::StatusOr<RveSnapshot> p = PreparePacking(set);
    ASSERT_FALSE(p.ok()) << c.field;
    EXPECT_EQ(p.status().code(), absl::StatusCode::kInvalidArgument) << p.status();
    EXPECT_TRUE(HasSubstr(p.status().message(), c.field + " = "));
  }
  ParameterSet bad_material = *base;
  bad_material.material.friction = -1.0;
  absl::StatusOr<RveSnapshot> p = PreparePacking(bad_material);
  EXPECT_EQ(p.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(HasSubstr(p.status().message(), "friction"));
  Controls bad_controls;
  bad_controls.time_step_factor = 2.0;
  p = PreparePacking(*base, bad_controls);
  EXPECT_EQ(p.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(HasSubstr(p.status().message(), "time_step_factor"));
}

TEST(ParameterSetTest, UnknownNameIsNotFoundAndListsTheNames) {
  const absl::StatusOr<ParameterSet> set = FindParameterSet("nope");
  ASSERT_FALSE(set.ok());
  EXPECT_EQ(set.status().code(), absl::StatusCode::kNotFound);
  EXPECT_TRUE(HasSubstr(set.status().message(), "'nope'"));
  const std::vector<std::string> names = ParameterSetNames();
  // shared/reference/README.md's nine sets, the saturated dense, medium
  // and loose ones of liang-zhao-wu-soga §4.2–4.3 and its §4.4 wave set.
  EXPECT_EQ(names.size(), 13u);
  for (const std::string& name : names) EXPECT_TRUE(HasSubstr(set.status().message(), name));
  EXPECT_FALSE(FindParameterSet("set-dense").ok());  // names are case-sensitive
}

TEST(ParseElementTestKindTest, UnknownNameListsTheKinds) {
  const absl::StatusOr<ElementTestKind> kind = ParseElementTestKind("triaxial");
  ASSERT_FALSE(kind.ok());
  EXPECT_EQ(kind.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(HasSubstr(kind.status().message(), "'triaxial'"));
  EXPECT_TRUE(HasSubstr(kind.status().message(), "drained-biaxial"));
  EXPECT_TRUE(HasSubstr(kind.status().message(), "cyclic-simple-shear"));
}

// --- RunElementTest. ---

TEST(RunElementTestTest, BadSpecIsRefusedAndTheRveUntouched) {
  struct Case {
    std::string field;
    std::function<void(ElementTestSpec&)> corrupt;
  };
  auto cyclic = [](ElementTestSpec& s) {
    s.kind = ElementTestKind::kCyclicSimpleShear;
    s.max_strain = 0.1;
  };
  const std::vector<Case> cases = {
      {"confining", [](ElementTestSpec& s) { s.confining = 0.0; }},
      {"confining", [](ElementTestSpec& s) { s.confining = -100e3; }},
      {"confining", [](ElementTestSpec& s) { s.confining = kNaN; }},
      {"confining", [](ElementTestSpec& s) { s.confining = kInf; }},
      {"max_strain", [](ElementTestSpec& s) { s.max_strain = 0.5; }},
      {"max_strain", [](ElementTestSpec& s) { s.max_strain = 0.0; }},
      // Below one DEM step's strain at the default I = 1e-3: refused before the
      // consolidation, like the rest, so the RVE stays untouched.
      {"max_strain", [](ElementTestSpec& s) { s.max_strain = 1e-308; }},
      {"max_strain", [](ElementTestSpec& s) { s.max_strain = 1e-6; }},
      {"max_strain",
       [](ElementTestSpec& s) {
         s.kind = ElementTestKind::kOedometer;
         s.max_strain = 0.6;
       }},
      {"max_strain",
       [](ElementTestSpec& s) {
         s.kind = ElementTestKind::kUndrainedSimpleShear;
         s.max_strain = 10.0;
       }},
      {"inertial_number", [](ElementTestSpec& s) { s.inertial_number = 0.0; }},
      {"inertial_number", [](ElementTestSpec& s) { s.inertial_number = 0.2; }},
      {"rows", [](ElementTestSpec& s) { s.rows = 1; }},
      {"axis", [](ElementTestSpec& s) { s.axis = 2; }},
      {"axis",
       [](ElementTestSpec& s) {
         s.kind = ElementTestKind::kIsotropic;
         s.axis = 0;
       }},
      {"cycles",
       [&](ElementTestSpec& s) {
         cyclic(s);
         s.cycles = 0;
       }},
      {"cycles",
       [&](ElementTestSpec& s) {
         cyclic(s);
         s.cycles = 10001;
       }},
      {"amplitude",
       [&](ElementTestSpec& s) {
         cyclic(s);
         s.amplitude = 0.0;
       }},
      {"amplitude",
       [&](ElementTestSpec& s) {
         cyclic(s);
         s.amplitude = 0.1;  // strain amplitude not below max_strain
       }},
  };
  Rve rve = CreateOrDie(Loaded());
  for (const Case& c : cases) {
    ElementTestSpec spec;
    c.corrupt(spec);
    bool progressed = false;
    const auto rows = RunElementTest(rve, spec, [&](double) { progressed = true; });
    ASSERT_FALSE(rows.ok()) << c.field;
    EXPECT_EQ(rows.status().code(), absl::StatusCode::kInvalidArgument) << rows.status();
    EXPECT_TRUE(HasSubstr(rows.status().message(), c.field + " = "));
    EXPECT_FALSE(progressed);
    ExpectIdenticalPackings(rve.ToSnapshot(), Loaded());
  }
}

// --- An RVE without contacts. ---

void ExpectAllFinite(const RveState& s) {
  EXPECT_TRUE(s.stress.allFinite());
  EXPECT_TRUE(s.fabric.allFinite());
  EXPECT_TRUE(s.fabric_anisotropy_tensor.allFinite());
  if (s.tangent) {
    EXPECT_TRUE(s.tangent->allFinite());
  }
  for (double v : {s.fabric_anisotropy, s.void_ratio, s.porosity, s.coordination,
                   s.mechanical_coordination, s.permeability, s.mean_rotation, s.kinetic_energy,
                   s.unbalanced_force_ratio, s.volume, s.time_step, s.mass_scale}) {
    EXPECT_TRUE(std::isfinite(v)) << v;
  }
}

TEST(DiluteTest, NoContactsGiveAZeroWellDefinedState) {
  // 12 discs of 2–4 mm on a 4×3 grid, 3 cm apart: no contacts, and moving
  // slowly enough that none form during the calls below.
  RveSnapshot p;
  p.cell << 0.12, 0.0, 0.0, 0.09;
  for (int k = 0; k < 12; ++k) {
    p.radius.push_back(2e-3 + 2e-3 * (k % 3) / 2.0);
    p.sx.push_back((k % 4 + 0.5) / 4.0);
    p.sy.push_back((k / 4 + 0.5) / 3.0);
    p.vx.push_back(1e-3 * (k % 2 == 0 ? 1 : -1));
    p.vy.push_back(0.0);
    p.omega.push_back(0.1 * k);
    p.theta.push_back(0.0);
  }
  p.permeability_coefficient = 1e-3;
  Rve rve = CreateOrDie(p);
  const RveState s = rve.Observe(/*want_tangent=*/true);
  ExpectAllFinite(s);
  EXPECT_EQ(s.num_contacts, 0);
  EXPECT_FALSE(s.fabric_defined);
  EXPECT_EQ(s.stress, Eigen::Matrix3d::Zero());
  EXPECT_EQ(s.fabric, Eigen::Matrix3d::Zero());
  EXPECT_EQ(s.fabric_anisotropy, 0.0);
  ASSERT_TRUE(s.tangent.has_value());
  EXPECT_EQ(s.tangent->norm(), 0.0);
  EXPECT_EQ(s.coordination, 0.0);
  EXPECT_EQ(s.mechanical_coordination, 0.0);
  EXPECT_EQ(s.unbalanced_force_ratio, 0.0);
  EXPECT_GT(s.kinetic_energy, 0.0);
  const double solid = SolidArea(p.radius);
  EXPECT_NEAR(s.void_ratio, (0.12 * 0.09 - solid) / solid, 1e-12);
  EXPECT_TRUE(rve.Contacts().empty());

  // Stepping, applying and relaxing a dilute RVE stays finite and contact-free.
  CellControl shear;
  shear.xy = {ControlMode::kStrainRate, 1.0};
  ExpectAllFinite(rve.Run(shear, 10));
  const absl::StatusOr<RveState> applied = rve.Apply(Diag(1.01, 0.99), {.want_tangent = true});
  ASSERT_TRUE(applied.ok()) << applied.status();
  ExpectAllFinite(*applied);
  EXPECT_EQ(applied->num_contacts, 0);
  EXPECT_EQ(applied->stress, Eigen::Matrix3d::Zero());
  const RveState relaxed = rve.Relax(1e-4, 100);
  ExpectAllFinite(relaxed);
  EXPECT_EQ(relaxed.steps, 100);  // no contacts: the ratio criterion never holds
  EXPECT_FALSE(relaxed.fabric_defined);
}

}  // namespace
}  // namespace rvehub::dem
