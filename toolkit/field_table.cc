#include "toolkit/field_table.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <map>
#include <system_error>

#include "absl/strings/str_cat.h"

namespace rvehub::fields {
namespace {

// Edit distance, for "did you mean" on unknown keys.
size_t Distance(absl::string_view a, absl::string_view b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}

}  // namespace

absl::StatusOr<Object> Object::Open(const Json& j, std::string ptr,
                                    const std::vector<absl::string_view>& keys) {
  if (!j.is_object()) return Bad(ptr, "must be an object, got ", Got(j));
  for (const auto& [key, value] : j.items()) {
    if (std::find(keys.begin(), keys.end(), key) != keys.end()) continue;
    std::string hint;
    size_t best = 3;  // suggest only near misses of longer keys
    for (absl::string_view k : keys) {
      if (const size_t d = Distance(key, k); d < best && k.size() > 3) {
        best = d;
        hint = absl::StrCat("did you mean \"", k, "\"? ");
      }
    }
    return Bad(Child(ptr, key), "unknown key (", hint, "keys here: ", absl::StrJoin(keys, ", "),
               ")");
  }
  return Object(j, std::move(ptr));
}

std::string Range::Rule(double x) const {
  if (std::isfinite(x) && ((hi == kMaxMagnitude && x > hi) || (lo == -kMaxMagnitude && x < lo))) {
    return absl::StrCat("must be at most ", Num(kMaxMagnitude), " in magnitude");
  }
  if (MustBePositive() && x > 0.0 && x < kMinPositive) {
    return absl::StrCat("must be at least ", Num(kMinPositive),
                        " (the smallest positive value a case takes)");
  }
  const double low = lo == -kMaxMagnitude ? -kInf : lo;
  const double high = hi == kMaxMagnitude ? kInf : hi;
  if (low == -kInf && high == kInf) return "must be a finite number";
  if (high == kInf) return absl::StrCat("must be ", lo_open ? "> " : ">= ", Num(low));
  if (low == -kInf) return absl::StrCat("must be ", hi_open ? "< " : "<= ", Num(high));
  return absl::StrCat("must be in ", lo_open ? "(" : "[", Num(low), ", ", Num(high),
                      hi_open ? ")" : "]");
}

absl::Status ReadNumber(const Json& v, absl::string_view ptr, const Range& range, double* out) {
  if (!v.is_number()) return Bad(ptr, "must be a number, got ", Got(v));
  const double x = v.get<double>();
  if (!std::isfinite(x) || !range.Contains(x)) return Bad(ptr, range.Rule(x), ", got ", Num(x));
  *out = x;
  return absl::OkStatus();
}

absl::Status ReadInteger(const Json& v, absl::string_view ptr, std::int64_t lo, std::int64_t hi,
                         std::int64_t* out) {
  const std::string rule = hi == std::numeric_limits<std::int64_t>::max()
                               ? absl::StrCat("must be an integer >= ", lo)
                               : absl::StrCat("must be an integer in ", lo, "..", hi);
  if (!v.is_number()) return Bad(ptr, rule, ", got ", Got(v));
  std::int64_t n = 0;
  if (v.is_number_unsigned()) {
    if (v.get<std::uint64_t>() > static_cast<std::uint64_t>(hi)) {
      return Bad(ptr, rule, ", got ", v.get<std::uint64_t>());
    }
    n = static_cast<std::int64_t>(v.get<std::uint64_t>());
  } else if (v.is_number_integer()) {
    n = v.get<std::int64_t>();
  } else {
    const double x = v.get<double>();
    if (!(x == std::floor(x) && x >= static_cast<double>(lo) && x <= static_cast<double>(hi))) {
      return Bad(ptr, rule, ", got ", Num(x));
    }
    n = static_cast<std::int64_t>(x);
  }
  if (n < lo || n > hi) return Bad(ptr, rule, ", got ", n);
  *out = n;
  return absl::OkStatus();
}

absl::Status ReadInt(const Json& v, absl::string_view ptr, int lo, int hi, int* out) {
  std::int64_t n = 0;
  RETURN_IF_ERROR(ReadInteger(v, ptr, lo, hi, &n));
  *out = static_cast<int>(n);
  return absl::OkStatus();
}

absl::Status ReadSeed(const Json& v, absl::string_view ptr, std::uint64_t* out) {
  if (v.is_number_unsigned()) {
    *out = v.get<std::uint64_t>();
    return absl::OkStatus();
  }
  if (v.is_number_float()) {  // e.g. 1e3
    const double x = v.get<double>();
    if (x >= 0 && x < 0x1p64 && x == std::floor(x)) {
      *out = static_cast<std::uint64_t>(x);
      return absl::OkStatus();
    }
  }
  return Bad(ptr, "must be an integer in 0..", std::numeric_limits<std::uint64_t>::max(), ", got ",
             Got(v));
}

absl::Status ReadString(const Json& v, absl::string_view ptr, bool non_empty, std::string* out) {
  if (!v.is_string()) return Bad(ptr, "must be a string, got ", Got(v));
  if (non_empty && v.get_ref<const std::string&>().empty()) {
    return Bad(ptr, "must be a non-empty string");
  }
  *out = v.get<std::string>();
  return absl::OkStatus();
}

absl::Status ReadName(const Json& v, absl::string_view ptr, std::string* out) {
  RETURN_IF_ERROR(ReadString(v, ptr, true, out));
  if (out->size() > kMaxNameLength) {
    return Bad(ptr, "names have at most ", kMaxNameLength, " characters, got ", out->size());
  }
  for (char c : *out) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.')) {
      return Bad(ptr, "names use letters, digits, '_', '-' and '.' only, got ", Quote(*out));
    }
  }
  return absl::OkStatus();
}

absl::Status ReadVec2(const Json& v, absl::string_view ptr, const Range& range,
                      Eigen::Vector2d* out) {
  if (!v.is_array() || v.size() != 2) {
    return Bad(ptr, "must be an array of 2 numbers [x, y], got ", Got(v));
  }
  Eigen::Vector2d x;
  for (int i = 0; i < 2; ++i) RETURN_IF_ERROR(ReadNumber(v[i], Child(ptr, i), range, &x[i]));
  *out = x;
  return absl::OkStatus();
}

absl::Status ReadTimeRows(const Json& j, const std::string& ptr, size_t width,
                          absl::string_view shape, bool non_empty,
                          std::vector<std::array<double, 3>>* rows) {
  if (!j.is_array() || (non_empty && j.empty())) {
    return Bad(ptr, non_empty ? "must be a non-empty array of " : "must be an array of ", shape,
               ", got ", Got(j));
  }
  for (size_t i = 0; i < j.size(); ++i) {
    const std::string at = Child(ptr, i);
    if (!j[i].is_array() || j[i].size() != width) {
      return Bad(at, "must be an array of ", width, " numbers ", shape, ", got ", Got(j[i]));
    }
    std::array<double, 3> row{};
    RETURN_IF_ERROR(ReadNumber(j[i][0], Child(at, 0), kNonNegative, &row[0]));
    for (size_t c = 1; c < width; ++c) {
      RETURN_IF_ERROR(ReadNumber(j[i][c], Child(at, c), kAny, &row[c]));
    }
    if (!rows->empty() && row[0] <= rows->back()[0]) {
      return Bad(Child(at, 0), "times must increase strictly, got ", Num(row[0]), " s after ",
                 Num(rows->back()[0]), " s");
    }
    rows->push_back(row);
  }
  return absl::OkStatus();
}

absl::Status GetNumber(const Object& o, absl::string_view key, Need need, const Range& range,
                       double* out) {
  const Json* v = o.Get(key);
  if (v == nullptr) return need == Need::kRequired ? o.Missing(key) : absl::OkStatus();
  return ReadNumber(*v, o.At(key), range, out);
}

absl::Status GetInteger(const Object& o, absl::string_view key, std::int64_t lo, std::int64_t hi,
                        std::int64_t* out) {
  const Json* v = o.Get(key);
  return v == nullptr ? absl::OkStatus() : ReadInteger(*v, o.At(key), lo, hi, out);
}

absl::Status GetString(const Object& o, absl::string_view key, Need need, bool non_empty,
                       std::string* out) {
  const Json* v = o.Get(key);
  if (v == nullptr) return need == Need::kRequired ? o.Missing(key) : absl::OkStatus();
  return ReadString(*v, o.At(key), non_empty, out);
}

absl::Status GetName(const Object& o, std::string* out) {
  const Json* v = o.Get("name");
  if (v == nullptr) return o.Missing("name");
  return ReadName(*v, o.At("name"), out);
}

absl::Status GetVec2(const Object& o, absl::string_view key, Need need, const Range& range,
                     Eigen::Vector2d* out) {
  const Json* v = o.Get(key);
  if (v == nullptr) return need == Need::kRequired ? o.Missing(key) : absl::OkStatus();
  return ReadVec2(*v, o.At(key), range, out);
}

absl::Status GetArray(const Object& o, absl::string_view key, Need need,
                      std::vector<const Json*>* out) {
  const Json* v = o.Get(key);
  if (v == nullptr) return need == Need::kRequired ? o.Missing(key) : absl::OkStatus();
  if (!v->is_array()) return Bad(o.At(key), "must be an array, got ", Got(*v));
  if (need == Need::kRequired && v->empty()) return Bad(o.At(key), "must not be empty");
  for (const Json& e : *v) out->push_back(&e);
  return absl::OkStatus();
}

absl::Status GetFile(const Object& o, absl::string_view key, const std::string& base_dir,
                     std::string* out) {
  std::string file;
  RETURN_IF_ERROR(GetString(o, key, Need::kRequired, true, &file));
  std::filesystem::path path(file);
  if (path.is_relative()) path = std::filesystem::path(base_dir) / path;
  std::error_code error;
  std::filesystem::path absolute = std::filesystem::absolute(path, error);
  if (!error) path = absolute;
  path = path.lexically_normal();
  if (!std::filesystem::is_regular_file(path, error)) {
    return Bad(o.At(key), "no such file ", Quote(path.string()));
  }
  *out = path.string();
  return absl::OkStatus();
}

absl::Status Forbid(const Object& o, absl::string_view key, absl::string_view why) {
  return o.Has(key) ? Bad(o.At(key), why) : absl::OkStatus();
}

absl::Status CheckUnique(const std::vector<std::string>& names, absl::string_view ptr,
                         absl::string_view what) {
  std::map<std::string, size_t> first;
  for (size_t i = 0; i < names.size(); ++i) {
    auto [it, inserted] = first.emplace(names[i], i);
    if (!inserted) {
      return Bad(Child(Child(ptr, i), "name"), "duplicate ", what, " name ", Quote(names[i]),
                 " (also ", Child(ptr, it->second), ")");
    }
  }
  return absl::OkStatus();
}

OrderedJson Vec2Json(const Eigen::Vector2d& v) { return OrderedJson::array({v.x(), v.y()}); }

}  // namespace rvehub::fields
