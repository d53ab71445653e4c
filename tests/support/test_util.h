// Helpers shared by the DEM engine tests: prepared packings cached per
// process, creation of an Rve that must succeed, a hand-built square lattice,
// and bit-for-bit comparison of packings and RVE states (doubles are compared
// by their bits: −0 differs from +0 and NaN equals itself).
#ifndef RVEHUB_TESTS_SUPPORT_TEST_UTIL_H_
#define RVEHUB_TESTS_SUPPORT_TEST_UTIL_H_

#include <Eigen/Dense>
#include <cstddef>
#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include "rve_server/engine/rve.h"
#include "rve_server/values/snapshot.h"

namespace rvehub::dem::testing_util {

// The packing of parameter set `name` (its seed, 1) as PreparePacking makes
// it. Preparing 400 discs takes 1–2 s: each set is prepared once per process.
// A failure is reported to the running test and gives an empty RveSnapshot.
const RveSnapshot& Prepared(const std::string& name);

// Rve::Create(packing), failing the test (and crashing) when it is refused.
Rve CreateOrDie(RveSnapshot packing);

// A side×side square lattice of discs at rest, centres `spacing` apart in a
// square periodic cell side·spacing wide; radius(x, y) gives the disc of
// column x and row y. Material, controls and reference cell are the defaults.
RveSnapshot SquareLattice(int side, double spacing, const std::function<double(int, int)>& radius);

// Bitwise equality of doubles, of vectors of doubles and of fixed-size Eigen
// matrices of doubles.
bool SameBits(double a, double b);
bool SameBits(const std::vector<double>& a, const std::vector<double>& b);

template <typename Derived>
bool SameBits(const Eigen::PlainObjectBase<Derived>& a, const Eigen::PlainObjectBase<Derived>& b) {
  return a.size() == b.size() &&
         std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<std::size_t>(a.size())) == 0;
}

// Element by element; a difference is reported (non-fatally) for the first
// index k that differs only, as what[k].
void ExpectSameBits(const std::vector<double>& a, const std::vector<double>& b, const char* what);
void ExpectSameBits(const Eigen::Matrix2d& a, const Eigen::Matrix2d& b, const char* what);

// Every field of the material and the controls, doubles bit for bit.
void ExpectSameMaterialAndControls(const RveSnapshot& a, const RveSnapshot& b);

// Every field of two packings, doubles bit for bit, contact history included.
// A single differing value gives a single non-fatal failure naming it.
void ExpectIdenticalPackings(const RveSnapshot& a, const RveSnapshot& b);
void ExpectIdenticalPackings(const RveSnapshot& a, const RveSnapshot& b, const std::string& where);

// Every field of two states, bit for bit.
void ExpectIdenticalStates(const RveState& a, const RveState& b, const std::string& where);

}  // namespace rvehub::dem::testing_util

#endif  // RVEHUB_TESTS_SUPPORT_TEST_UTIL_H_
