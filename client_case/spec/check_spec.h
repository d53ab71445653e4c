// A case's validation checks (cases/FORMAT.md, "checks"): each compares one
// figure of the run's summary.json with a reference from the literature or
// from a measured run, within a stated tolerance. Plain data, standard
// library only, like the other specs a client's core may hold.
#ifndef RVEHUB_CLIENT_CASE_SPEC_CHECK_SPEC_H_
#define RVEHUB_CLIENT_CASE_SPEC_CHECK_SPEC_H_

#include <string>

namespace rvehub::client_case {

struct CheckSpec {
  // A key of summary.json as the client writes it ("N_q", "peak_stress_Pa").
  std::string quantity;
  // The reference, in the quantity's units; unused when reference_quantity
  // is set.
  double reference = 0.0;
  // Another key of the same summary.json as the reference instead (a
  // closed-form value the summary computes, such as "N_q_reduced"); empty:
  // the number above.
  std::string reference_quantity;
  // Passes when |value − reference| ≤ tolerance (absolute, the quantity's
  // units) or ≤ tolerance·|reference| (relative, [-]).
  bool relative = true;
  double tolerance = 0.0;
  // Which side of the reference the check guards: both, or only that the
  // value is at most reference + allowed (kUpper: the reference is an upper
  // bound) or at least reference − allowed (kLower). A paper that says
  // "smaller than the dry column's" gives a bound, not a band.
  enum class Bound { kBoth, kUpper, kLower };
  Bound bound = Bound::kBoth;
  // Where the reference comes from: paper, section, figure or table, or the
  // reduced case's own measured run.
  std::string source;
};

}  // namespace rvehub::client_case

#endif  // RVEHUB_CLIENT_CASE_SPEC_CHECK_SPEC_H_
