#include "client_run/checks.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "nlohmann/json.hpp"

namespace rvehub::client_run {
namespace {

using Bound = client_case::CheckSpec::Bound;

const double* Find(const Summary& summary, const std::string& key) {
  for (const auto& [k, v] : summary) {
    if (k == key) return &v;
  }
  return nullptr;
}

}  // namespace

std::vector<CheckResult> EvaluateChecks(std::span<const client_case::CheckSpec> checks,
                                        const Summary& summary) {
  std::vector<CheckResult> out;
  for (const client_case::CheckSpec& c : checks) {
    CheckResult r;
    r.check = c;
    r.reference = c.reference;
    const double* value = Find(summary, c.quantity);
    const double* reference =
        c.reference_quantity.empty() ? &c.reference : Find(summary, c.reference_quantity);
    if (value == nullptr) {
      r.missing = c.quantity;
    } else if (reference == nullptr) {
      r.missing = c.reference_quantity;
    } else {
      r.found = true;
      r.value = *value;
      r.reference = *reference;
      r.allowed = c.relative ? c.tolerance * std::abs(r.reference) : c.tolerance;
      // NaN compares false: a non-finite figure fails.
      const double off = r.value - r.reference;
      const bool within = c.bound == Bound::kUpper   ? off <= r.allowed
                          : c.bound == Bound::kLower ? -off <= r.allowed
                                                     : std::abs(off) <= r.allowed;
      r.pass = std::isfinite(r.value) && within;
    }
    out.push_back(std::move(r));
  }
  return out;
}

bool AllPass(std::span<const CheckResult> results) {
  for (const CheckResult& r : results) {
    if (!r.pass) return false;
  }
  return true;
}

std::vector<std::string> SummaryAndCheckLines(const Summary& summary,
                                              std::span<const client_case::CheckSpec> checks,
                                              bool* all_pass) {
  std::vector<std::string> lines;
  for (const auto& [key, value] : summary) {
    lines.push_back(absl::StrFormat("summary: %s = %.6g", key, value));
  }
  const std::vector<CheckResult> results = EvaluateChecks(checks, summary);
  for (const CheckResult& r : results) lines.push_back("check: " + FormatCheck(r));
  if (all_pass != nullptr) *all_pass = AllPass(results);
  return lines;
}

bool PrintSummaryAndChecks(const Summary& summary, std::span<const client_case::CheckSpec> checks) {
  bool all_pass = false;
  for (const std::string& line : SummaryAndCheckLines(summary, checks, &all_pass)) {
    std::printf("%s\n", line.c_str());
  }
  return all_pass;
}

std::string FormatCheck(const CheckResult& r) {
  const client_case::CheckSpec& c = r.check;
  // "± 10 %" for a band; "at most … + 0" or "at least … − 5 %" for a bound.
  const char* sign = c.bound == Bound::kUpper ? "+" : c.bound == Bound::kLower ? "−" : "±";
  const std::string tolerance = c.relative
                                    ? absl::StrFormat("%s %.6g %%", sign, 100.0 * c.tolerance)
                                    : absl::StrFormat("%s %.6g", sign, c.tolerance);
  const char* side = c.bound == Bound::kUpper   ? "at most "
                     : c.bound == Bound::kLower ? "at least "
                                                : "";
  const std::string reference_name =
      c.reference_quantity.empty() ? "" : absl::StrCat(c.reference_quantity, " = ");
  if (!r.found) {
    const std::string reference =
        c.reference_quantity.empty() ? absl::StrFormat("%.6g", c.reference) : c.reference_quantity;
    return absl::StrCat("FAIL ", c.quantity, ": ", r.missing, " is not in summary.json (reference ",
                        side, reference, " ", tolerance, "; ", c.source, ")");
  }
  return absl::StrFormat("%s %s = %.6g (reference %s%s%.6g %s = %.6g; %s)",
                         r.pass ? "pass" : "FAIL", c.quantity, r.value, side, reference_name,
                         r.reference, tolerance, r.allowed, c.source);
}

absl::StatusOr<Summary> ReadSummary(const std::string& path) {
  std::ifstream f(path);
  if (!f) return absl::NotFoundError(absl::StrCat("cannot read ", path));
  std::stringstream text;
  text << f.rdbuf();
  const nlohmann::ordered_json j = nlohmann::ordered_json::parse(text.str(), nullptr, false);
  if (!j.is_object()) return absl::InvalidArgumentError(absl::StrCat(path, ": not a JSON object"));
  Summary summary;
  for (const auto& [key, value] : j.items()) {
    if (value.is_number()) summary.emplace_back(key, value.get<double>());
  }
  return summary;
}

}  // namespace rvehub::client_run
