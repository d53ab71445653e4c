// The "checks" section: a case's validation checks against summary.json.
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "client_case/sections.h"
#include "rve_server/common/status_macros.h"
#include "toolkit/field_table.h"

namespace rvehub::client_case {
namespace {

using fields::Bad;
using fields::GetEnum;
using fields::GetNumber;
using fields::GetString;
using fields::Got;
using fields::Json;
using fields::kAny;
using fields::Need;
using fields::Num;
using fields::Object;
using fields::OrderedJson;
using fields::Range;
using fields::ReadNumber;

// summary.json's keys are short ASCII identifiers with SI units in the name;
// anything else is a typo that would only show as a missing figure later.
absl::Status ReadKey(const Json& v, const std::string& ptr, std::string* out) {
  if (!v.is_string() || v.get_ref<const std::string&>().empty()) {
    return Bad(ptr, "must be a non-empty string (a key of summary.json), got ", Got(v));
  }
  const std::string& s = v.get_ref<const std::string&>();
  if (s.size() > 64) return Bad(ptr, "keys of summary.json have at most 64 characters");
  for (char c : s) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '_' || c == '.' || c == '-';
    if (!ok) {
      return Bad(ptr, "keys of summary.json use letters, digits, '_', '-' and '.' only, got ",
                 fields::Quote(s));
    }
  }
  *out = s;
  return absl::OkStatus();
}

// A relative tolerance above 10 (1000 %) says nothing; an absolute one may be
// 0 for a flag such as front_at_rest.
constexpr Range kRelativeTolerance{0.0, 10.0, true, false};
constexpr Range kAbsoluteTolerance{0.0, fields::kMaxMagnitude, false, false};

constexpr fields::Table<CheckSpec::Bound> kBounds = {{"upper", CheckSpec::Bound::kUpper},
                                                     {"lower", CheckSpec::Bound::kLower}};

absl::Status ParseCheck(const Json& j, const std::string& ptr, CheckSpec* c) {
  ASSIGN_OR_RETURN(Object o, Object::Open(j, ptr,
                                          {"quantity", "reference", "relative_tolerance",
                                           "absolute_tolerance", "bound", "source"}));
  const Json* quantity = o.Get("quantity");
  if (quantity == nullptr) return o.Missing("quantity");
  RETURN_IF_ERROR(ReadKey(*quantity, o.At("quantity"), &c->quantity));
  const Json* reference = o.Get("reference");
  if (reference == nullptr) return o.Missing("reference");
  if (reference->is_string()) {
    RETURN_IF_ERROR(ReadKey(*reference, o.At("reference"), &c->reference_quantity));
    if (c->reference_quantity == c->quantity) {
      return Bad(o.At("reference"), "is the checked quantity itself");
    }
  } else if (reference->is_number()) {
    RETURN_IF_ERROR(ReadNumber(*reference, o.At("reference"), kAny, &c->reference));
  } else {
    return Bad(o.At("reference"), "must be a number or a key of summary.json, got ",
               Got(*reference));
  }
  if (o.Has("relative_tolerance") == o.Has("absolute_tolerance")) {
    return Bad(ptr, "give exactly one of \"relative_tolerance\" ([-], of the reference) or ",
               "\"absolute_tolerance\" (in the quantity's units)");
  }
  c->relative = o.Has("relative_tolerance");
  if (c->relative) {
    RETURN_IF_ERROR(
        GetNumber(o, "relative_tolerance", Need::kRequired, kRelativeTolerance, &c->tolerance));
    // Against 0 every relative band is empty: a check that cannot pass.
    if (c->reference_quantity.empty() && c->reference == 0.0) {
      return Bad(o.At("relative_tolerance"),
                 "a relative tolerance needs a non-zero reference (give absolute_tolerance)");
    }
  } else {
    RETURN_IF_ERROR(
        GetNumber(o, "absolute_tolerance", Need::kRequired, kAbsoluteTolerance, &c->tolerance));
  }
  RETURN_IF_ERROR(GetEnum(o, "bound", Need::kOptional, "bound", kBounds, &c->bound));
  return GetString(o, "source", Need::kRequired, true, &c->source);
}

}  // namespace

absl::Status ParseChecks(const Json& j, const std::string& ptr, std::vector<CheckSpec>* checks) {
  if (!j.is_array()) return Bad(ptr, "must be an array of checks, got ", Got(j));
  std::vector<CheckSpec> read(j.size());
  for (std::size_t i = 0; i < j.size(); ++i) {
    RETURN_IF_ERROR(ParseCheck(j[i], fields::Child(ptr, i), &read[i]));
  }
  *checks = std::move(read);
  return absl::OkStatus();
}

OrderedJson WriteChecks(const std::vector<CheckSpec>& checks) {
  OrderedJson out = OrderedJson::array();
  for (const CheckSpec& c : checks) {
    OrderedJson j;
    j["quantity"] = c.quantity;
    if (c.reference_quantity.empty()) {
      j["reference"] = c.reference;
    } else {
      j["reference"] = c.reference_quantity;
    }
    j[c.relative ? "relative_tolerance" : "absolute_tolerance"] = c.tolerance;
    if (c.bound != CheckSpec::Bound::kBoth) {
      j["bound"] = c.bound == CheckSpec::Bound::kUpper ? "upper" : "lower";
    }
    j["source"] = c.source;
    out.push_back(std::move(j));
  }
  return out;
}

}  // namespace rvehub::client_case
