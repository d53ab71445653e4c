#include "mpm_client/case.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "rve_server/common/status_macros.h"
#include "rve_server/common/text_file.h"
#include "rve_server/values/material.h"
#include "rve_server/values/snapshot.h"

namespace rvehub::mpm {
namespace {

using Json = nlohmann::json;
using OrderedJson = nlohmann::ordered_json;

constexpr double kInf = std::numeric_limits<double>::infinity();
// Coordinates within this fraction of a cell of a grid line are on it (and
// snapped onto it): decimal inputs such as 0.3 with h = 0.1 are not exact.
constexpr double kGridTolerance = 1e-6;

constexpr double kMaxEndTime = 1e6;  // s

// ---------------------------------------------------------------- messages

// RFC 6901 escaping of one reference token.
std::string Escape(absl::string_view token) {
  std::string out;
  for (char c : token) {
    if (c == '~') {
      out += "~0";
    } else if (c == '/') {
      out += "~1";
    } else {
      out += c;
    }
  }
  return out;
}

std::string Child(absl::string_view ptr, absl::string_view key) {
  return absl::StrCat(ptr, "/", Escape(key));
}
std::string Child(absl::string_view ptr, size_t index) { return absl::StrCat(ptr, "/", index); }

template <typename... Args>
absl::Status Bad(absl::string_view ptr, const Args&... what) {
  return absl::InvalidArgumentError(
      absl::StrCat(ptr.empty() ? absl::string_view("(document)") : ptr, ": ", what...));
}

// Enough digits to tell 0.3 from 0.30001, fewer than a full round trip.
std::string Num(double x) { return absl::StrFormat("%.10g", x); }

std::string Quote(absl::string_view s) { return absl::StrCat("\"", s, "\""); }

// "string \"abc\"", "array [1,2]", "null": for "got ..." in type errors.
std::string Got(const Json& v) {
  if (v.is_null()) return "null";
  std::string text = v.dump(-1, ' ', false, Json::error_handler_t::replace);
  if (text.size() > 60) text = text.substr(0, 57) + "...";
  return absl::StrCat(v.type_name(), " ", text);
}

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

// ---------------------------------------------------------------- readers

// A JSON object at `ptr` whose keys are all in an allowed list.
class Object {
 public:
  static absl::StatusOr<Object> Open(const Json& j, std::string ptr,
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

  const std::string& ptr() const { return ptr_; }
  std::string At(absl::string_view key) const { return Child(ptr_, key); }
  // The value of `key`, null when absent.
  const Json* Get(absl::string_view key) const {
    auto it = j_->find(std::string(key));
    return it == j_->end() ? nullptr : &*it;
  }
  bool Has(absl::string_view key) const { return Get(key) != nullptr; }
  absl::Status Missing(absl::string_view key) const {
    return Bad(At(key), "required key is missing");
  }

 private:
  Object(const Json& j, std::string ptr) : j_(&j), ptr_(std::move(ptr)) {}
  const Json* j_;
  std::string ptr_;
};

enum class Need { kOptional, kRequired };

// Every number of a case is at most 1e12 in magnitude (fields with a
// physical range have tighter bounds): products of a few case values, such as
// ρ·|g|·depth, then stay far from overflow.
constexpr double kMaxMagnitude = 1e12;
// And a number that must be > 0 is at least 1e-12: a thickness, density or
// permeability of 1e-308 passed as positive, then its quotients overflowed
// to NaN mid-run (points "at (nan, nan)", a pressure solve "not converged").
constexpr double kMinPositive = 1e-12;

// An allowed interval of a real number, open or closed at either end.
struct Range {
  double lo = -kInf;
  double hi = kInf;
  bool lo_open = false;
  bool hi_open = false;

  bool MustBePositive() const { return lo == 0.0 && lo_open; }
  bool Contains(double x) const {
    if (MustBePositive() && x < kMinPositive) return false;
    return (lo_open ? x > lo : x >= lo) && (hi_open ? x < hi : x <= hi);
  }
  // What is wrong with x; the generic bounds on magnitude are only named
  // when x breaks them.
  std::string Rule(double x) const {
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
};
constexpr Range kAny{-kMaxMagnitude, kMaxMagnitude, false, false};
constexpr Range kPositive{0.0, kMaxMagnitude, true, false};
constexpr Range kNonNegative{0.0, kMaxMagnitude, false, false};
constexpr Range kUnit{0.0, 1.0, false, false};

absl::Status ReadNumber(const Json& v, absl::string_view ptr, const Range& range, double* out) {
  if (!v.is_number()) return Bad(ptr, "must be a number, got ", Got(v));
  const double x = v.get<double>();
  if (!std::isfinite(x) || !range.Contains(x)) return Bad(ptr, range.Rule(x), ", got ", Num(x));
  *out = x;
  return absl::OkStatus();
}

// Integral JSON numbers, including floats such as 1e3.
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

// Names of templates, regions, walls, bodies and tractions end up in file
// and column names, so they are restricted to a portable alphabet. A
// template's also goes onto the servers after the run id (up to 88
// characters, MakeRunId) and a '.', within their 128: hence at most 32.
inline constexpr std::size_t kMaxCaseNameLength = 32;

absl::Status ReadName(const Json& v, absl::string_view ptr, std::string* out) {
  RETURN_IF_ERROR(ReadString(v, ptr, true, out));
  if (out->size() > kMaxCaseNameLength) {
    return Bad(ptr, "names have at most ", kMaxCaseNameLength, " characters, got ", out->size());
  }
  for (char c : *out) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.')) {
      return Bad(ptr, "names use letters, digits, '_', '-' and '.' only, got ", Quote(*out));
    }
  }
  return absl::OkStatus();
}

template <typename T>
using Table = std::initializer_list<std::pair<absl::string_view, T>>;

template <typename T>
std::string Choices(Table<T> table) {
  std::vector<absl::string_view> names;
  for (const auto& [name, value] : table) names.push_back(name);
  return absl::StrJoin(names, ", ");
}

template <typename T>
absl::Status ReadEnum(const Json& v, absl::string_view ptr, absl::string_view what, Table<T> table,
                      T* out) {
  if (!v.is_string()) {
    return Bad(ptr, "must be a string (", Choices(table), "), got ", Got(v));
  }
  const std::string& s = v.get_ref<const std::string&>();
  for (const auto& [name, value] : table) {
    if (name == s) {
      *out = value;
      return absl::OkStatus();
    }
  }
  return Bad(ptr, "unknown ", what, " ", Quote(s), " (", Choices(table), ")");
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

// Optional or required keys of an object, left untouched when absent.
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

template <typename T>
absl::Status GetEnum(const Object& o, absl::string_view key, Need need, absl::string_view what,
                     Table<T> table, T* out) {
  const Json* v = o.Get(key);
  if (v == nullptr) return need == Need::kRequired ? o.Missing(key) : absl::OkStatus();
  return ReadEnum(*v, o.At(key), what, table, out);
}

absl::Status GetVec2(const Object& o, absl::string_view key, Need need, const Range& range,
                     Eigen::Vector2d* out) {
  const Json* v = o.Get(key);
  if (v == nullptr) return need == Need::kRequired ? o.Missing(key) : absl::OkStatus();
  return ReadVec2(*v, o.At(key), range, out);
}

// The elements of an optional (or required non-empty) array of objects.
absl::Status GetArray(const Object& o, absl::string_view key, Need need,
                      std::vector<const Json*>* out) {
  const Json* v = o.Get(key);
  if (v == nullptr) return need == Need::kRequired ? o.Missing(key) : absl::OkStatus();
  if (!v->is_array()) return Bad(o.At(key), "must be an array, got ", Got(*v));
  if (need == Need::kRequired && v->empty()) return Bad(o.At(key), "must not be empty");
  for (const Json& e : *v) out->push_back(&e);
  return absl::OkStatus();
}

absl::Status Forbid(const Object& o, absl::string_view key, absl::string_view why) {
  return o.Has(key) ? Bad(o.At(key), why) : absl::OkStatus();
}

// Names must be unique within a list; `ptr` is the list's pointer.
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

template <typename T>
std::vector<std::string> NamesOf(const std::vector<T>& items) {
  std::vector<std::string> names;
  for (const T& item : items) names.push_back(item.name);
  return names;
}

// ---------------------------------------------------------------- field tables

// One key of a section, once: how it is read from a case file (with its
// validation) and how the canonical writer writes it back. A section's
// table lists its keys in order; the reader reads them in that order (so a
// rule may look at keys read before it), the writer writes them so.
template <typename S>
struct Field {
  absl::string_view key;
  std::function<absl::Status(const Object&, S*)> read;
  // Writes the key into `j`, or nothing where the spec does not use it.
  std::function<void(const S&, OrderedJson&)> write;
};
template <typename S>
using Fields = std::vector<Field<S>>;

OrderedJson Vec(const Eigen::Vector2d& v) { return OrderedJson::array({v.x(), v.y()}); }

template <typename S>
Field<S> NumberField(absl::string_view key, double S::*m, Need need, Range range) {
  return {key, [=](const Object& o, S* s) { return GetNumber(o, key, need, range, &(s->*m)); },
          [=](const S& s, OrderedJson& j) { j[std::string(key)] = s.*m; }};
}

template <typename S>
Field<S> Vec2Field(absl::string_view key, Eigen::Vector2d S::*m, Need need, Range range) {
  return {key, [=](const Object& o, S* s) { return GetVec2(o, key, need, range, &(s->*m)); },
          [=](const S& s, OrderedJson& j) { j[std::string(key)] = Vec(s.*m); }};
}

template <typename S>
Field<S> IntegerField(absl::string_view key, std::int64_t S::*m, std::int64_t lo, std::int64_t hi) {
  return {key, [=](const Object& o, S* s) { return GetInteger(o, key, lo, hi, &(s->*m)); },
          [=](const S& s, OrderedJson& j) { j[std::string(key)] = s.*m; }};
}

template <typename S>
Field<S> TextField(absl::string_view key, std::string S::*m, Need need, bool non_empty) {
  return {key, [=](const Object& o, S* s) { return GetString(o, key, need, non_empty, &(s->*m)); },
          [=](const S& s, OrderedJson& j) { j[std::string(key)] = s.*m; }};
}

// A flag, false when absent; written only when true.
template <typename S>
Field<S> FlagField(absl::string_view key, bool S::*m) {
  return {key,
          [=](const Object& o, S* s) -> absl::Status {
            const Json* v = o.Get(key);
            if (v == nullptr) return absl::OkStatus();
            if (!v->is_boolean()) return Bad(o.At(key), "must be true or false, got ", Got(*v));
            s->*m = v->get<bool>();
            return absl::OkStatus();
          },
          [=](const S& s, OrderedJson& j) {
            if (s.*m) j[std::string(key)] = true;
          }};
}

template <typename S>
Field<S> NameField() {
  return {"name", [](const Object& o, S* s) { return GetName(o, &s->name); },
          [](const S& s, OrderedJson& j) { j["name"] = s.name; }};
}

// An enumeration: read by `table` (aliases allowed), written as name(value).
// `table` must have static storage (a constexpr Table).
template <typename S, typename T>
Field<S> EnumField(absl::string_view key, T S::*m, Need need, absl::string_view what,
                   Table<T> table, absl::string_view (*name)(T)) {
  return {key, [=](const Object& o, S* s) { return GetEnum(o, key, need, what, table, &(s->*m)); },
          [=](const S& s, OrderedJson& j) { j[std::string(key)] = name(s.*m); }};
}

// `field` only where `applies` holds for what was read before it; elsewhere
// the key is refused (`why`) and not written.
template <typename S>
Field<S> Only(bool (*applies)(const S&), absl::string_view why, Field<S> field) {
  return {field.key,
          [=](const Object& o, S* s) {
            return applies(*s) ? field.read(o, s) : Forbid(o, field.key, why);
          },
          [=](const S& s, OrderedJson& j) {
            if (applies(s)) field.write(s, j);
          }};
}

template <typename S>
std::vector<absl::string_view> KeysOf(const Fields<S>& fields) {
  std::vector<absl::string_view> keys;
  for (const Field<S>& f : fields) keys.push_back(f.key);
  return keys;
}

// Opens the section's object (unknown keys refused) and reads every field.
template <typename S>
absl::StatusOr<Object> ReadFields(const Json& j, const std::string& ptr, const Fields<S>& fields,
                                  S* s) {
  ASSIGN_OR_RETURN(Object o, Object::Open(j, ptr, KeysOf(fields)));
  for (const Field<S>& f : fields) RETURN_IF_ERROR(f.read(o, s));
  return o;
}

template <typename S>
OrderedJson WriteFields(const Fields<S>& fields, const S& s) {
  OrderedJson j = OrderedJson::object();
  for (const Field<S>& f : fields) f.write(s, j);
  return j;
}

// ---------------------------------------------------------------- sections

constexpr absl::string_view kAxisName[2] = {"x", "y"};

// Grid lines along each axis: x_i = origin + i·h, i in 0..n.
class GridLines {
 public:
  explicit GridLines(const GridSpec& grid) : grid_(grid) {}

  // The index of the grid line at coordinate `x` along `axis`; the snapped
  // coordinate goes to `snapped`.
  absl::Status Snap(double x, int axis, absl::string_view ptr, int* index, double* snapped) const {
    const double origin = grid_.origin[axis];
    const int n = axis == 0 ? grid_.nx : grid_.ny;
    const double k = (x - origin) / grid_.cell_size;
    const double i = std::round(k);
    if (std::abs(k - i) > kGridTolerance) {
      return Bad(ptr, kAxisName[axis], " = ", Num(x), " m is not on a grid line (origin ",
                 Num(origin), " m, cell size ", Num(grid_.cell_size), " m)");
    }
    if (i < 0 || i > n) {
      return Bad(ptr, kAxisName[axis], " = ", Num(x), " m is outside the grid, ", kAxisName[axis],
                 " in [", Num(origin), ", ", Num(origin + n * grid_.cell_size), "] m");
    }
    *index = static_cast<int>(i);
    *snapped = origin + *index * grid_.cell_size;
    return absl::OkStatus();
  }

 private:
  GridSpec grid_;
};

// Bounded so that node and cell counts fit an int.
constexpr int kMaxCells = 100000;
constexpr std::int64_t kMaxTotalCells = 100000000;

Fields<GridSpec> GridFields() {
  return {
      Vec2Field("origin", &GridSpec::origin, Need::kOptional, kAny),
      NumberField("cell_size", &GridSpec::cell_size, Need::kRequired, kPositive),
      {"cells",
       [](const Object& o, GridSpec* grid) -> absl::Status {
         const Json* cells = o.Get("cells");
         if (cells == nullptr) return o.Missing("cells");
         if (!cells->is_array() || cells->size() != 2) {
           return Bad(o.At("cells"), "must be an array of 2 integers [nx, ny], got ", Got(*cells));
         }
         RETURN_IF_ERROR(ReadInt((*cells)[0], Child(o.At("cells"), 0), 1, kMaxCells, &grid->nx));
         RETURN_IF_ERROR(ReadInt((*cells)[1], Child(o.At("cells"), 1), 1, kMaxCells, &grid->ny));
         if (static_cast<std::int64_t>(grid->nx) * grid->ny > kMaxTotalCells) {
           return Bad(o.At("cells"), "at most ", kMaxTotalCells, " cells, got ", grid->nx, " × ",
                      grid->ny);
         }
         return absl::OkStatus();
       },
       [](const GridSpec& g, OrderedJson& j) {
         j["cells"] = OrderedJson::array({g.nx, g.ny});
       }},
  };
}

absl::Status ParseGrid(const Json& j, const std::string& ptr, GridSpec* grid) {
  return ReadFields(j, ptr, GridFields(), grid).status();
}

constexpr Table<ShapeKind> kShapes = {{"linear", ShapeKind::kLinear}, {"gimp", ShapeKind::kGimp}};

absl::string_view ShapeName(ShapeKind kind) { return kind == ShapeKind::kGimp ? "gimp" : "linear"; }

constexpr Table<LostPointPolicy> kLostPointPolicies = {{"stop", LostPointPolicy::kStop},
                                                       {"drop", LostPointPolicy::kDrop}};

absl::string_view LostPointPolicyName(LostPointPolicy p) {
  return p == LostPointPolicy::kDrop ? "drop" : "stop";
}

constexpr Table<FBar> kFBars = {{"none", FBar::kNone}, {"nodal", FBar::kNodal}};

// A shaking table's speeds are of cm/s to m/s; its frequencies of Hz.
constexpr Range kShakingSpeed{-100.0, 100.0, false, false};   // m/s
constexpr Range kShakingFrequency{0.0, 1000.0, true, false};  // Hz

bool IsShaken(const Wall& w) { return !w.shaking_amplitude.isZero(0.0); }
bool IsShakenBox(const SolverSpec& s) { return !s.shaking_amplitude.isZero(0.0); }

// A shake's two keys (a wall's or the whole box's): shaking_amplitude, m/s,
// written only when shaken; shaking_frequency, Hz, required then and
// refused otherwise.
template <typename S>
Field<S> ShakingAmplitudeField(Eigen::Vector2d S::*m, bool (*shaken)(const S&)) {
  return {"shaking_amplitude",
          [m](const Object& o, S* s) {
            return GetVec2(o, "shaking_amplitude", Need::kOptional, kShakingSpeed, &(s->*m));
          },
          [m, shaken](const S& s, OrderedJson& j) {
            if (shaken(s)) j["shaking_amplitude"] = Vec(s.*m);
          }};
}
template <typename S>
Field<S> ShakingFrequencyField(double S::*m, bool (*shaken)(const S&)) {
  return Only(shaken, "only with a shaking_amplitude other than [0, 0]",
              NumberField("shaking_frequency", m, Need::kRequired, kShakingFrequency));
}

// Read only where the time step comes from the RVEs' tangent (time_step and
// wave_modulus read before it are 0); written only when on.
Field<SolverSpec> TimeStepUpdateField() {
  constexpr absl::string_view kKey = "time_step_update_every";
  return {kKey,
          [=](const Object& o, SolverSpec* s) -> absl::Status {
            if (s->time_step > 0 || s->wave_modulus > 0) {
              return Forbid(o, kKey,
                            "only where the time step comes from the RVEs' tangent "
                            "(solver.time_step and solver.wave_modulus 0)");
            }
            return GetInteger(o, kKey, 0, 1'000'000'000, &s->time_step_update_every);
          },
          [=](const SolverSpec& s, OrderedJson& j) {
            if (s.time_step_update_every > 0) j[std::string(kKey)] = s.time_step_update_every;
          }};
}

Fields<SolverSpec> SolverFields() {
  return {
      EnumField("shape", &SolverSpec::shape, Need::kOptional, "shape function", kShapes,
                &ShapeName),
      NumberField("pic_fraction", &SolverSpec::pic_fraction, Need::kOptional, kUnit),
      Vec2Field("gravity", &SolverSpec::gravity, Need::kOptional, kAny),
      NumberField("time_step", &SolverSpec::time_step, Need::kOptional, Range{0.0, kMaxEndTime}),
      NumberField("cfl", &SolverSpec::cfl, Need::kOptional, Range{0.0, 1.0, true, false}),
      NumberField("wave_modulus", &SolverSpec::wave_modulus, Need::kOptional, kNonNegative),
      TimeStepUpdateField(),
      // A bound that keeps end_time / Δt a step count (1e308 s overflowed it
      // and ended the run at step 0); the step count itself is bounded at the
      // start.
      NumberField("end_time", &SolverSpec::end_time, Need::kRequired,
                  Range{0.0, kMaxEndTime, true, false}),
      NumberField("thickness", &SolverSpec::thickness, Need::kOptional, kPositive),
      ShakingAmplitudeField(&SolverSpec::shaking_amplitude, &IsShakenBox),
      ShakingFrequencyField(&SolverSpec::shaking_frequency, &IsShakenBox),
      EnumField("lost_points", &SolverSpec::lost_points, Need::kOptional, "lost-point policy",
                kLostPointPolicies, &LostPointPolicyName),
      NumberField("mass_scale", &SolverSpec::mass_scale, Need::kOptional,
                  Range{1.0, 1e6, false, false}),
      EnumField("f_bar", &SolverSpec::f_bar, Need::kOptional, "F-bar kind", kFBars, &FBarName),
      NumberField("nonlocal_radius", &SolverSpec::nonlocal_radius, Need::kOptional, kNonNegative),
      NumberField("nonlocal_fraction", &SolverSpec::nonlocal_fraction, Need::kOptional,
                  Range{0.0, 1.0, true, false}),
  };
}

absl::Status ParseSolver(const Json& j, const std::string& ptr, SolverSpec* solver) {
  return ReadFields(j, ptr, SolverFields(), solver).status();
}

bool FromSet(const TemplateSpec& t) { return t.file.empty(); }

// A file named by `key`, relative to `base_dir` (the case file's directory)
// unless absolute, as an absolute normal path (a checkpointed spec does not
// depend on the working directory); it must exist.
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

// Keys that shape the preparation: a template file holds its own packing.
absl::Status OnlyFromParameterSet(const Object& o, absl::string_view key) {
  if (o.Has("parameter_set")) return absl::OkStatus();
  return Forbid(o, key,
                "only for templates prepared from a parameter set (a file holds its own packing)");
}

// `base_dir`: the case file's directory, for relative template files.
Fields<TemplateSpec> TemplateFields(const std::string& base_dir) {
  return {
      NameField<TemplateSpec>(),
      {"parameter_set",
       [](const Object& o, TemplateSpec* t) -> absl::Status {
         if (o.Has("file") == o.Has("parameter_set")) {
           return Bad(o.ptr(),
                      "give exactly one of \"file\" (a template file) or \"parameter_set\" ",
                      "(prepare from a named parameter set)");
         }
         if (!o.Has("parameter_set")) return absl::OkStatus();
         RETURN_IF_ERROR(Forbid(o, "template_name", "only for templates read from a file"));
         RETURN_IF_ERROR(GetString(o, "parameter_set", Need::kRequired, true, &t->parameter_set));
         if (!dem::FindParameterSet(t->parameter_set).ok()) {
           return Bad(o.At("parameter_set"), "unknown parameter set ", Quote(t->parameter_set),
                      " (known: ", absl::StrJoin(dem::ParameterSetNames(), ", "), ")");
         }
         return absl::OkStatus();
       },
       [](const TemplateSpec& t, OrderedJson& j) {
         if (FromSet(t)) j["parameter_set"] = t.parameter_set;
       }},
      {"seed",
       [](const Object& o, TemplateSpec* t) -> absl::Status {
         RETURN_IF_ERROR(OnlyFromParameterSet(o, "seed"));
         const Json* seed = o.Get("seed");
         return seed == nullptr ? absl::OkStatus() : ReadSeed(*seed, o.At("seed"), &t->seed);
       },
       [](const TemplateSpec& t, OrderedJson& j) {
         if (FromSet(t)) j["seed"] = t.seed;
       }},
      {"pressure",
       [](const Object& o, TemplateSpec* t) -> absl::Status {
         RETURN_IF_ERROR(OnlyFromParameterSet(o, "pressure"));
         return GetNumber(o, "pressure", Need::kOptional,
                          Range{0.0, dem::kMaxPressure, true, false}, &t->pressure);
       },
       [](const TemplateSpec& t, OrderedJson& j) {
         if (FromSet(t) && t.pressure > 0) j["pressure"] = t.pressure;
       }},
      {"void_ratio",
       [](const Object& o, TemplateSpec* t) -> absl::Status {
         RETURN_IF_ERROR(OnlyFromParameterSet(o, "void_ratio"));
         return GetNumber(o, "void_ratio", Need::kOptional, Range{0.0, 1.0, true, true},
                          &t->void_ratio);
       },
       [](const TemplateSpec& t, OrderedJson& j) {
         if (FromSet(t) && t.void_ratio > 0) j["void_ratio"] = t.void_ratio;
       }},
      {"particles",
       [](const Object& o, TemplateSpec* t) -> absl::Status {
         RETURN_IF_ERROR(OnlyFromParameterSet(o, "particles"));
         std::int64_t n = t->particles;
         RETURN_IF_ERROR(
             GetInteger(o, "particles", 2, static_cast<std::int64_t>(dem::kMaxParticles), &n));
         t->particles = static_cast<int>(n);
         return absl::OkStatus();
       },
       [](const TemplateSpec& t, OrderedJson& j) {
         if (FromSet(t) && t.particles > 0) j["particles"] = t.particles;
       }},
      {"rolling_eta",
       [](const Object& o, TemplateSpec* t) -> absl::Status {
         RETURN_IF_ERROR(OnlyFromParameterSet(o, "rolling_eta"));
         if (!o.Has("rolling_eta")) return absl::OkStatus();
         double eta = 0;
         RETURN_IF_ERROR(GetNumber(o, "rolling_eta", Need::kRequired,
                                   Range{0.0, dem::kMaxRollingEta, false, false}, &eta));
         // The set is known here: "parameter_set" is read first.
         const absl::StatusOr<dem::ParameterSet> set = dem::FindParameterSet(t->parameter_set);
         if (set.ok() && !dem::HasRollingResistance(set->material)) {
           return Bad(o.At("rolling_eta"), "parameter set ", Quote(t->parameter_set),
                      " has no rolling resistance (β = 0)");
         }
         t->rolling_eta = eta;
         return absl::OkStatus();
       },
       [](const TemplateSpec& t, OrderedJson& j) {
         if (FromSet(t) && t.rolling_eta.has_value()) j["rolling_eta"] = *t.rolling_eta;
       }},
      {"file",
       [base_dir](const Object& o, TemplateSpec* t) -> absl::Status {
         return o.Has("file") ? GetFile(o, "file", base_dir, &t->file) : absl::OkStatus();
       },
       [](const TemplateSpec& t, OrderedJson& j) {
         if (!FromSet(t)) j["file"] = t.file;
       }},
      {"template_name",
       [](const Object& o, TemplateSpec* t) {
         return o.Has("file")
                    ? GetString(o, "template_name", Need::kOptional, true, &t->template_name)
                    : absl::OkStatus();
       },
       [](const TemplateSpec& t, OrderedJson& j) {
         if (!FromSet(t) && !t.template_name.empty()) j["template_name"] = t.template_name;
       }},
  };
}

absl::Status ParseTemplate(const Json& j, const std::string& ptr, const std::string& base_dir,
                           TemplateSpec* t) {
  return ReadFields(j, ptr, TemplateFields(base_dir), t).status();
}

// A region's extent in grid cells, for the overlap and free-surface checks.
struct CellBox {
  int lo[2] = {0, 0};
  int hi[2] = {0, 0};
};

constexpr Table<InitialStressKind> kInitialStresses = {
    {"template", InitialStressKind::kTemplate},
    {"geostatic_isotropic", InitialStressKind::kIsotropic},
    {"geostatic_k0", InitialStressKind::kK0}};

absl::string_view InitialStressName(InitialStressKind kind) {
  switch (kind) {
    case InitialStressKind::kTemplate:
      break;
    case InitialStressKind::kIsotropic:
      return "geostatic_isotropic";
    case InitialStressKind::kK0:
      return "geostatic_k0";
  }
  return "template";
}

bool K0(const MaterialRegion& r) { return r.initial_stress == InitialStressKind::kK0; }
bool Geostatic(const MaterialRegion& r) { return r.initial_stress != InitialStressKind::kTemplate; }

// The keys of a region's "initial_stress" object.
Fields<MaterialRegion> InitialStressFields() {
  constexpr absl::string_view kOnlyGeostatic = "only for the geostatic kinds";
  return {
      EnumField("kind", &MaterialRegion::initial_stress, Need::kRequired, "initial stress kind",
                kInitialStresses, &InitialStressName),
      Only(&K0, "only for kind \"geostatic_k0\"",
           NumberField("k0", &MaterialRegion::k0, Need::kOptional, kPositive)),
      Only(&Geostatic, kOnlyGeostatic,
           NumberField("surface_y", &MaterialRegion::surface_y, Need::kOptional, kAny)),
      Only(&Geostatic, kOnlyGeostatic,
           NumberField("surcharge", &MaterialRegion::surcharge, Need::kOptional, kNonNegative)),
      Only(&Geostatic, kOnlyGeostatic,
           NumberField("minimum", &MaterialRegion::minimum_stress, Need::kOptional, kNonNegative)),
  };
}

absl::Status ParseInitialStress(const Json& j, const std::string& ptr, const SolverSpec& solver,
                                MaterialRegion* r) {
  ASSIGN_OR_RETURN(Object o, ReadFields(j, ptr, InitialStressFields(), r));
  // RVEs need p > 0: without gravity σv is the surcharge (or the minimum).
  if (r->initial_stress != InitialStressKind::kTemplate && solver.gravity.isZero(0.0) &&
      r->surcharge == 0.0 && r->minimum_stress == 0.0) {
    return Bad(o.At("kind"), "a geostatic start without gravity needs a surcharge or a minimum ",
               "> 0 (RVEs need p > 0)");
  }
  return absl::OkStatus();
}

// What reading a region needs besides its JSON (null members: only writing).
struct RegionContext {
  const GridLines* lines = nullptr;
  const SolverSpec* solver = nullptr;
  const std::vector<TemplateSpec>* templates = nullptr;
  CellBox* box = nullptr;
};

Fields<MaterialRegion> RegionFields(const RegionContext& c) {
  return {
      NameField<MaterialRegion>(),
      Vec2Field("lower", &MaterialRegion::lower, Need::kRequired, kAny),
      {"upper",
       [c](const Object& o, MaterialRegion* r) -> absl::Status {
         RETURN_IF_ERROR(GetVec2(o, "upper", Need::kRequired, kAny, &r->upper));
         // Both corners on grid lines, upper above lower: at least one cell.
         for (int axis = 0; axis < 2; ++axis) {
           RETURN_IF_ERROR(c.lines->Snap(r->lower[axis], axis, Child(o.At("lower"), axis),
                                         &c.box->lo[axis], &r->lower[axis]));
           RETURN_IF_ERROR(c.lines->Snap(r->upper[axis], axis, Child(o.At("upper"), axis),
                                         &c.box->hi[axis], &r->upper[axis]));
           if (c.box->hi[axis] <= c.box->lo[axis]) {
             return Bad(Child(o.At("upper"), axis), "upper ", kAxisName[axis], " = ",
                        Num(r->upper[axis]), " m must be above lower ", kAxisName[axis], " = ",
                        Num(r->lower[axis]), " m (a region spans at least one cell)");
           }
         }
         return absl::OkStatus();
       },
       [](const MaterialRegion& r, OrderedJson& j) { j["upper"] = Vec(r.upper); }},
      {"points_per_cell_side",
       [](const Object& o, MaterialRegion* r) -> absl::Status {
         const Json* v = o.Get("points_per_cell_side");
         return v == nullptr
                    ? absl::OkStatus()
                    : ReadInt(*v, o.At("points_per_cell_side"), 1, 8, &r->points_per_cell_side);
       },
       [](const MaterialRegion& r, OrderedJson& j) {
         j["points_per_cell_side"] = r.points_per_cell_side;
       }},
      {"template",
       [c](const Object& o, MaterialRegion* r) -> absl::Status {
         RETURN_IF_ERROR(GetString(o, "template", Need::kRequired, true, &r->rve_template));
         if (std::none_of(c.templates->begin(), c.templates->end(),
                          [&](const TemplateSpec& t) { return t.name == r->rve_template; })) {
           return Bad(o.At("template"), "no template named ", Quote(r->rve_template),
                      " (templates: ", absl::StrJoin(NamesOf(*c.templates), ", "), ")");
         }
         return absl::OkStatus();
       },
       [](const MaterialRegion& r, OrderedJson& j) { j["template"] = r.rve_template; }},
      NumberField("density", &MaterialRegion::density, Need::kOptional, kNonNegative),
      {"initial_stress",
       [c](const Object& o, MaterialRegion* r) -> absl::Status {
         r->surface_y = r->upper.y();  // the region's top unless stated
         const Json* v = o.Get("initial_stress");
         return v == nullptr ? absl::OkStatus()
                             : ParseInitialStress(*v, o.At("initial_stress"), *c.solver, r);
       },
       [](const MaterialRegion& r, OrderedJson& j) {
         j["initial_stress"] = WriteFields(InitialStressFields(), r);
       }},
  };
}

absl::Status ParseRegion(const Json& j, const std::string& ptr, const GridLines& lines,
                         const SolverSpec& solver, const std::vector<TemplateSpec>& templates,
                         MaterialRegion* r, CellBox* box) {
  return ReadFields(j, ptr, RegionFields({&lines, &solver, &templates, box}), r).status();
}

absl::Status CheckOverlaps(const std::vector<MaterialRegion>& regions,
                           const std::vector<CellBox>& boxes, absl::string_view ptr) {
  for (size_t b = 0; b < boxes.size(); ++b) {
    for (size_t a = 0; a < b; ++a) {
      const CellBox& p = boxes[a];
      const CellBox& q = boxes[b];
      if (p.lo[0] < q.hi[0] && q.lo[0] < p.hi[0] && p.lo[1] < q.hi[1] && q.lo[1] < p.hi[1]) {
        return Bad(Child(ptr, b), "region ", Quote(regions[b].name), " overlaps region ",
                   Quote(regions[a].name), " (", Child(ptr, a), ")");
      }
    }
  }
  return absl::OkStatus();
}

constexpr Table<ContactKind> kWallKinds = {
    {"fixed", ContactKind::kRough},     {"rough", ContactKind::kRough},
    {"roller", ContactKind::kSmooth},   {"smooth", ContactKind::kSmooth},
    {"symmetry", ContactKind::kSmooth}, {"frictional", ContactKind::kFrictional}};
constexpr Table<ContactKind> kBodyContacts = {{"rough", ContactKind::kRough},
                                              {"smooth", ContactKind::kSmooth},
                                              {"frictional", ContactKind::kFrictional}};

absl::string_view ContactKindName(ContactKind kind) {
  switch (kind) {
    case ContactKind::kRough:
      return "rough";
    case ContactKind::kSmooth:
      return "smooth";
    case ContactKind::kFrictional:
      return "frictional";
  }
  return "rough";
}

// μ: required and > 0 for frictional contact, absent otherwise.
absl::Status GetFriction(const Object& o, ContactKind kind, absl::string_view kind_key,
                         double* friction) {
  if (kind != ContactKind::kFrictional) {
    return Forbid(o, "friction", absl::StrCat("only for ", kind_key, " \"frictional\""));
  }
  return GetNumber(o, "friction", Need::kRequired, kPositive, friction);
}

constexpr Table<int> kAxes = {{"x", 0}, {"y", 1}};
absl::string_view AxisName(int axis) { return kAxisName[axis == 0 ? 0 : 1]; }

// μ of a contact `kind_key` ("kind" or "contact"): required and > 0 for
// frictional contact, refused otherwise; written only where it applies.
template <typename S>
Field<S> FrictionField(absl::string_view kind_key) {
  return {"friction",
          [=](const Object& o, S* s) { return GetFriction(o, s->contact, kind_key, &s->friction); },
          [](const S& s, OrderedJson& j) {
            if (s.contact == ContactKind::kFrictional) j["friction"] = s.friction;
          }};
}

// A number that is infinite (never, unbounded) unless given; written only
// when finite.
template <typename S>
Field<S> OptionalFiniteField(absl::string_view key, double S::*m, Range range) {
  return {
      key,
      [=](const Object& o, S* s) { return GetNumber(o, key, Need::kOptional, range, &(s->*m)); },
      [=](const S& s, OrderedJson& j) {
        if (std::isfinite(s.*m)) j[std::string(key)] = s.*m;
      }};
}

// `lines`: the grid's, for snapping the position (null when only writing).
Fields<Wall> WallFields(const GridLines* lines) {
  return {
      NameField<Wall>(),
      EnumField("kind", &Wall::contact, Need::kRequired, "wall kind", kWallKinds, &ContactKindName),
      EnumField("line", &Wall::axis, Need::kRequired, "wall line", kAxes, &AxisName),
      {"position",
       [lines](const Object& o, Wall* w) -> absl::Status {
         RETURN_IF_ERROR(GetNumber(o, "position", Need::kRequired, kAny, &w->position));
         int index = 0;
         return lines->Snap(w->position, w->axis, o.At("position"), &index, &w->position);
       },
       [](const Wall& w, OrderedJson& j) { j["position"] = w.position; }},
      FrictionField<Wall>("kind"),
      OptionalFiniteField("remove_time", &Wall::remove_time, kNonNegative),
      FlagField("unilateral", &Wall::unilateral),
      ShakingAmplitudeField(&Wall::shaking_amplitude, &IsShaken),
      ShakingFrequencyField(&Wall::shaking_frequency, &IsShaken),
  };
}

absl::Status ParseWall(const Json& j, const std::string& ptr, const GridLines& lines, Wall* w) {
  return ReadFields(j, ptr, WallFields(&lines), w).status();
}

// An array of rows [t, v...] of `width` numbers (at most 3; `shape` names
// them in messages, e.g. "[t, vx, vy] (s, m/s, m/s)"): times >= 0 and
// increasing strictly, values finite. The unused entries of a row are 0.
absl::Status ParseTimeRows(const Json& j, const std::string& ptr, size_t width,
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

absl::Status ParseVelocity(const Json& j, const std::string& ptr,
                           std::vector<VelocityPoint>* history) {
  std::vector<std::array<double, 3>> rows;
  RETURN_IF_ERROR(ParseTimeRows(j, ptr, 3, "[t, vx, vy] (s, m/s, m/s)", false, &rows));
  for (const auto& [t, vx, vy] : rows) history->push_back({t, Eigen::Vector2d(vx, vy)});
  return absl::OkStatus();
}

absl::Status ParseLoadHistory(const Json& j, const std::string& ptr,
                              std::vector<LoadFactorPoint>* history) {
  std::vector<std::array<double, 3>> rows;
  RETURN_IF_ERROR(ParseTimeRows(j, ptr, 2, "[t, factor] (s, -)", true, &rows));
  for (const auto& row : rows) history->push_back({row[0], row[1]});
  return absl::OkStatus();
}

constexpr Table<RigidBody::Shape> kBodyShapes = {{"rectangle", RigidBody::Shape::kRectangle},
                                                 {"circle", RigidBody::Shape::kCircle}};
absl::string_view BodyShapeName(RigidBody::Shape shape) {
  return shape == RigidBody::Shape::kCircle ? "circle" : "rectangle";
}
bool Rectangle(const RigidBody& b) { return b.shape == RigidBody::Shape::kRectangle; }
bool Circle(const RigidBody& b) { return b.shape == RigidBody::Shape::kCircle; }

Fields<RigidBody> BodyFields() {
  return {
      NameField<RigidBody>(),
      EnumField("shape", &RigidBody::shape, Need::kRequired, "body shape", kBodyShapes,
                &BodyShapeName),
      Vec2Field("center", &RigidBody::center, Need::kRequired, kAny),
      Only(&Rectangle, "only for shape \"rectangle\"",
           Vec2Field("half_size", &RigidBody::half_size, Need::kRequired, kPositive)),
      Only(&Circle, "only for shape \"circle\"",
           NumberField("radius", &RigidBody::radius, Need::kRequired, kPositive)),
      EnumField("contact", &RigidBody::contact, Need::kOptional, "body contact", kBodyContacts,
                &ContactKindName),
      FrictionField<RigidBody>("contact"),
      {"velocity",
       [](const Object& o, RigidBody* b) -> absl::Status {
         const Json* v = o.Get("velocity");
         return v == nullptr ? absl::OkStatus() : ParseVelocity(*v, o.At("velocity"), &b->velocity);
       },
       [](const RigidBody& b, OrderedJson& j) {
         OrderedJson& velocity = j["velocity"] = OrderedJson::array();
         for (const VelocityPoint& p : b.velocity) {
           velocity.push_back(OrderedJson::array({p.time, p.velocity.x(), p.velocity.y()}));
         }
       }},
  };
}

absl::Status ParseBody(const Json& j, const std::string& ptr, RigidBody* b) {
  return ReadFields(j, ptr, BodyFields(), b).status();
}

struct Surface {
  int axis;
  int sign;
};
constexpr Table<Surface> kSurfaces = {
    {"+x", {0, 1}}, {"-x", {0, -1}}, {"+y", {1, 1}}, {"-y", {1, -1}}};

std::string SurfaceName(int axis, int sign) {
  return absl::StrCat(sign > 0 ? "+" : "-", kAxisName[axis]);
}

// `regions`: the case's, for the region's check (null when only writing).
Fields<SurfaceTraction> TractionFields(const std::vector<MaterialRegion>* regions) {
  return {
      NameField<SurfaceTraction>(),
      {"region",
       [regions](const Object& o, SurfaceTraction* t) -> absl::Status {
         RETURN_IF_ERROR(GetString(o, "region", Need::kRequired, true, &t->region));
         if (std::none_of(regions->begin(), regions->end(),
                          [&](const MaterialRegion& r) { return r.name == t->region; })) {
           return Bad(o.At("region"), "no region named ", Quote(t->region),
                      " (regions: ", absl::StrJoin(NamesOf(*regions), ", "), ")");
         }
         return absl::OkStatus();
       },
       [](const SurfaceTraction& t, OrderedJson& j) { j["region"] = t.region; }},
      {"surface",
       [](const Object& o, SurfaceTraction* t) -> absl::Status {
         Surface surface{0, 1};
         RETURN_IF_ERROR(GetEnum(o, "surface", Need::kRequired, "surface", kSurfaces, &surface));
         t->normal_axis = surface.axis;
         t->normal_sign = surface.sign;
         return absl::OkStatus();
       },
       [](const SurfaceTraction& t, OrderedJson& j) {
         j["surface"] = SurfaceName(t.normal_axis == 0 ? 0 : 1, t.normal_sign);
       }},
      // Read as the traction it makes; the writer writes that traction.
      {"pressure",
       [](const Object& o, SurfaceTraction* t) -> absl::Status {
         if (o.Has("pressure") == o.Has("traction")) {
           return Bad(o.ptr(), "give exactly one of \"pressure\" (Pa, compression +) or ",
                      "\"traction\" ([tx, ty], Pa, tension +)");
         }
         if (!o.Has("pressure")) return absl::OkStatus();
         double pressure = 0.0;
         RETURN_IF_ERROR(GetNumber(o, "pressure", Need::kRequired, kAny, &pressure));
         // A pressure pushes against the outward normal n: t = −p·n.
         t->traction = Eigen::Vector2d::Zero();
         t->traction[t->normal_axis] = -pressure * t->normal_sign;
         return absl::OkStatus();
       },
       [](const SurfaceTraction&, OrderedJson&) {}},
      {"traction",
       [](const Object& o, SurfaceTraction* t) {
         return o.Has("traction") ? GetVec2(o, "traction", Need::kRequired, kAny, &t->traction)
                                  : absl::OkStatus();
       },
       [](const SurfaceTraction& t, OrderedJson& j) { j["traction"] = Vec(t.traction); }},
      NumberField("ramp_time", &SurfaceTraction::ramp_time, Need::kOptional, kNonNegative),
      {"history",
       [](const Object& o, SurfaceTraction* t) -> absl::Status {
         const Json* h = o.Get("history");
         if (h == nullptr) return absl::OkStatus();
         if (t->ramp_time > 0.0) {
           return Bad(o.At("history"), "give either \"history\" or \"ramp_time\", not both");
         }
         return ParseLoadHistory(*h, o.At("history"), &t->history);
       },
       [](const SurfaceTraction& t, OrderedJson& j) {
         if (t.history.empty()) return;
         OrderedJson& history = j["history"] = OrderedJson::array();
         for (const LoadFactorPoint& p : t.history) {
           history.push_back(OrderedJson::array({p.time, p.factor}));
         }
       }},
      OptionalFiniteField("from", &SurfaceTraction::from, kAny),
      OptionalFiniteField("to", &SurfaceTraction::to, kAny),
  };
}

absl::Status ParseTraction(const Json& j, const std::string& ptr,
                           const std::vector<MaterialRegion>& regions,
                           const std::vector<CellBox>& boxes, const std::string& regions_ptr,
                           SurfaceTraction* t) {
  ASSIGN_OR_RETURN(Object o, ReadFields(j, ptr, TractionFields(&regions), t));
  if (!(t->from < t->to)) {
    return Bad(o.At("to"), "must be > from = ", Num(t->from), " m, got ", Num(t->to));
  }
  auto region = std::find_if(regions.begin(), regions.end(),
                             [&](const MaterialRegion& r) { return r.name == t->region; });
  const Surface surface{t->normal_axis, t->normal_sign};

  // The loaded part of the face, [lo, hi] along the other axis, must exist
  // and be free: not shared with a neighbouring region.
  const size_t index = region - regions.begin();
  const int along = 1 - surface.axis;
  const double face_lo = std::max(region->lower[along], t->from);
  const double face_hi = std::min(region->upper[along], t->to);
  const std::string face = absl::StrCat("the ", SurfaceName(surface.axis, surface.sign),
                                        " face of region ", Quote(region->name));
  if (!(face_lo < face_hi)) {
    return Bad(o.At(o.Has("from") ? "from" : "to"), "[from, to] = [", Num(t->from), ", ",
               Num(t->to), "] m misses ", face, ", ", kAxisName[along], " in [",
               Num(region->lower[along]), ", ", Num(region->upper[along]), "] m");
  }
  const CellBox& box = boxes[index];
  const int line = surface.sign > 0 ? box.hi[surface.axis] : box.lo[surface.axis];
  for (size_t k = 0; k < regions.size(); ++k) {
    const CellBox& other = boxes[k];
    const int other_line = surface.sign > 0 ? other.lo[surface.axis] : other.hi[surface.axis];
    if (k == index || other_line != line) continue;
    const double lo = std::max(face_lo, regions[k].lower[along]);
    const double hi = std::min(face_hi, regions[k].upper[along]);
    if (lo < hi) {
      return Bad(o.At("surface"), face, " touches region ", Quote(regions[k].name), " (",
                 Child(regions_ptr, k), ") for ", kAxisName[along], " in [", Num(lo), ", ", Num(hi),
                 "] m: not a free surface (narrow the load with from/to)");
    }
  }
  return absl::OkStatus();
}

Fields<RveSpec> RveFields() {
  // I above 0.1 is a dense flow, not a quasi-static RVE; more than 10^5 DEM
  // steps per increment is a mistake, not a setting.
  return {
      NumberField("max_inertial_number", &RveSpec::max_inertial_number, Need::kOptional,
                  Range{0.0, 0.1}),
      IntegerField("min_steps", &RveSpec::min_steps, 0, 100000),
      NumberField("max_stretch", &RveSpec::max_stretch, Need::kOptional, Range{0.0, 0.5}),
      FlagField("real_time", &RveSpec::real_time),
      FlagField("full_state_every_step", &RveSpec::full_state_every_step),
      NumberField("max_void_ratio", &RveSpec::max_void_ratio, Need::kOptional, Range{0.0, 10.0}),
  };
}

absl::Status ParseRve(const Json& j, const std::string& ptr, RveSpec* rve) {
  RETURN_IF_ERROR(ReadFields(j, ptr, RveFields(), rve).status());
  // Below the densest 2-D disc packings (e ≈ 0.1) it would be no cap but a
  // different material.
  if (rve->max_void_ratio > 0.0 && rve->max_void_ratio < 0.1) {
    return Bad(ptr + "/max_void_ratio", "must be 0 (no cap) or in [0.1, 10], got ",
               Num(rve->max_void_ratio));
  }
  // A stretch of more than half in one MPM step is a broken continuum, not
  // an increment; below 0.01 nearly every flow would stop.
  if (rve->max_stretch > 0.0 && rve->max_stretch < 0.01) {
    return Bad(ptr + "/max_stretch", "must be 0 (the template's) or in [0.01, 0.5], got ",
               Num(rve->max_stretch));
  }
  return absl::OkStatus();
}

// Static storage for the list (the table outlives every read).
const Table<std::string> kPlots = {{"stress-strain", "stress-strain"},
                                   {"load-settlement", "load-settlement"},
                                   {"collapse", "collapse"},
                                   {"none", "none"}};

bool LoadSettlement(const OutputSpec& o) { return o.plot == "load-settlement"; }
bool StressStrain(const OutputSpec& o) { return o.plot == "stress-strain"; }

const Table<std::string> kSummaries = {{"footing", "footing"},
                                       {"pipe", "pipe"},
                                       {"collapse", "collapse"},
                                       {"biaxial", "biaxial"},
                                       {"none", "none"}};

bool FootingSummary(const OutputSpec& o) {
  return o.summary == "footing" || (o.summary.empty() && o.plot == "load-settlement");
}

// `bodies`: the case's, for the plot body's check (null when only writing).
// `base_dir`: the case file's directory, for a relative reference curve.
Fields<OutputSpec> OutputFields(const std::vector<RigidBody>* bodies, const std::string& base_dir) {
  constexpr std::int64_t kMax = std::numeric_limits<std::int64_t>::max();
  constexpr absl::string_view kOnlyLoadSettlement = "only for plot \"load-settlement\"";
  Field<OutputSpec> plot_body = TextField("plot_body", &OutputSpec::plot_body, Need::kRequired,
                                          /*non_empty=*/true);
  const auto read_body = plot_body.read;
  plot_body.read = [=](const Object& o, OutputSpec* out) -> absl::Status {
    RETURN_IF_ERROR(read_body(o, out));
    if (bodies != nullptr && std::none_of(bodies->begin(), bodies->end(), [&](const RigidBody& b) {
          return b.name == out->plot_body;
        })) {
      return Bad(o.At("plot_body"), "no body named ", Quote(out->plot_body),
                 " (bodies: ", absl::StrJoin(NamesOf(*bodies), ", "), ")");
    }
    return absl::OkStatus();
  };
  return {
      IntegerField("frame_every", &OutputSpec::frame_every, 1, kMax),
      {"frame_times",
       [](const Object& o, OutputSpec* out) -> absl::Status {
         const Json* v = o.Get("frame_times");
         if (v == nullptr) return absl::OkStatus();
         if (!v->is_array()) return Bad(o.At("frame_times"), "must be an array of times (s)");
         for (std::size_t i = 0; i < v->size(); ++i) {
           double t = 0.0;
           RETURN_IF_ERROR(ReadNumber((*v)[i], Child(o.At("frame_times"), i), kNonNegative, &t));
           if (!out->frame_times.empty() && !(t > out->frame_times.back())) {
             return Bad(Child(o.At("frame_times"), i), "times must increase, got ", Num(t),
                        " s after ", Num(out->frame_times.back()), " s");
           }
           out->frame_times.push_back(t);
         }
         return absl::OkStatus();
       },
       [](const OutputSpec& out, OrderedJson& j) {
         if (!out.frame_times.empty()) j["frame_times"] = out.frame_times;
       }},
      IntegerField("timeseries_every", &OutputSpec::timeseries_every, 1, kMax),
      IntegerField("checkpoint_every", &OutputSpec::checkpoint_every, 0, kMax),
      IntegerField("progress_every", &OutputSpec::progress_every, 1, kMax),
      {"plot",
       [](const Object& o, OutputSpec* out) {
         return GetEnum(o, "plot", Need::kOptional, "plot", kPlots, &out->plot);
       },
       [](const OutputSpec& out, OrderedJson& j) { j["plot"] = out.plot; }},
      Only(&LoadSettlement, kOnlyLoadSettlement, plot_body),
      Only(&LoadSettlement, kOnlyLoadSettlement,
           NumberField("plot_width", &OutputSpec::plot_width, Need::kOptional, kPositive)),
      {"summary",
       [](const Object& o, OutputSpec* out) {
         return GetEnum(o, "summary", Need::kOptional, "summary", kSummaries, &out->summary);
       },
       [](const OutputSpec& out, OrderedJson& j) {
         if (!out.summary.empty()) j["summary"] = out.summary;
       }},
      Only(&FootingSummary, "only for a footing summary",
           {"phi_deg",
            [](const Object& o, OutputSpec* out) {
              return GetNumber(o, "phi_deg", Need::kOptional, Range{0.0, 90.0, true, true},
                               &out->phi_deg);
            },
            [](const OutputSpec& out, OrderedJson& j) {
              if (out.phi_deg > 0.0) j["phi_deg"] = out.phi_deg;
            }}),
      Only(&StressStrain, "only for plot \"stress-strain\"",
           {"reference_curve",
            [base_dir](const Object& o, OutputSpec* out) {
              return o.Has("reference_curve")
                         ? GetFile(o, "reference_curve", base_dir, &out->reference_curve)
                         : absl::OkStatus();
            },
            [](const OutputSpec& out, OrderedJson& j) {
              if (!out.reference_curve.empty()) j["reference_curve"] = out.reference_curve;
            }}),
  };
}

absl::Status ParseOutput(const Json& j, const std::string& ptr,
                         const std::vector<RigidBody>& bodies, const std::string& base_dir,
                         OutputSpec* out) {
  return ReadFields(j, ptr, OutputFields(&bodies, base_dir), out).status();
}

// Parses a list section: each element with `parse`, then unique names.
template <typename T, typename F>
absl::Status ParseList(const Object& root, absl::string_view key, Need need, absl::string_view what,
                       std::vector<T>* items, F parse) {
  std::vector<const Json*> elements;
  RETURN_IF_ERROR(GetArray(root, key, need, &elements));
  const std::string ptr = root.At(key);
  items->resize(elements.size());
  for (size_t i = 0; i < elements.size(); ++i) {
    RETURN_IF_ERROR(parse(*elements[i], Child(ptr, i), i, &(*items)[i]));
  }
  return CheckUnique(NamesOf(*items), ptr, what);
}

// ---------------------------------------------------------------- phases

Fields<DrainedBoundary> DrainedFields(const GridLines* lines) {
  return {
      NameField<DrainedBoundary>(),
      EnumField("line", &DrainedBoundary::axis, Need::kRequired, "drained line", kAxes, &AxisName),
      {"position",
       [lines](const Object& o, DrainedBoundary* d) -> absl::Status {
         RETURN_IF_ERROR(GetNumber(o, "position", Need::kRequired, kAny, &d->position));
         int index = 0;
         return lines->Snap(d->position, d->axis, o.At("position"), &index, &d->position);
       },
       [](const DrainedBoundary& d, OrderedJson& j) { j["position"] = d.position; }},
      NumberField("pressure", &DrainedBoundary::pressure, Need::kOptional, kAny),
      OptionalFiniteField("from", &DrainedBoundary::from, kAny),
      OptionalFiniteField("to", &DrainedBoundary::to, kAny),
  };
}

Fields<PressureMonitor> MonitorFields() {
  return {
      NameField<PressureMonitor>(),
      Vec2Field("position", &PressureMonitor::position, Need::kRequired, kAny),
  };
}

// Fluid density up to that of mercury; k up to that of clean gravel (×10).
constexpr Range kFluidDensity{0.0, 2e4, true, false};
constexpr Range kPermeability{0.0, 10.0, true, false};
constexpr Range kPorosity{0.0, 1.0, false, true};

constexpr Table<Projection> kProjections = {{"incremental", Projection::kIncremental},
                                            {"stabilised", Projection::kStabilised}};

absl::string_view ProjectionName(Projection p) {
  return p == Projection::kStabilised ? "stabilised" : "incremental";
}

constexpr Table<ExcessDatum> kExcessData = {{"water_table", ExcessDatum::kWaterTable},
                                            {"surface", ExcessDatum::kSurface}};

absl::string_view ExcessDatumName(ExcessDatum d) {
  return d == ExcessDatum::kSurface ? "surface" : "water_table";
}

Fields<PhasesSpec> PhasesFields() {
  return {
      EnumField("projection", &PhasesSpec::projection, Need::kOptional, "projection", kProjections,
                &ProjectionName),
      NumberField("fluid_density", &PhasesSpec::fluid_density, Need::kOptional, kFluidDensity),
      NumberField("permeability", &PhasesSpec::permeability, Need::kRequired, kPermeability),
      NumberField("porosity", &PhasesSpec::porosity, Need::kOptional, kPorosity),
      OptionalFiniteField("water_table", &PhasesSpec::water_table, kAny),
      FlagField("drained_free_surface", &PhasesSpec::drained_free_surface),
      FlagField("free_surface_beside_light_nodes", &PhasesSpec::free_surface_beside_light_nodes),
      EnumField("excess_pressure_from", &PhasesSpec::excess_from, Need::kOptional,
                "excess pressure datum", kExcessData, &ExcessDatumName),
      // Read by ParsePhases (lists); written here.
      {"drained", [](const Object&, PhasesSpec*) { return absl::OkStatus(); },
       [](const PhasesSpec& s, OrderedJson& j) {
         OrderedJson& list = j["drained"] = OrderedJson::array();
         for (const DrainedBoundary& d : s.drained)
           list.push_back(WriteFields(DrainedFields(nullptr), d));
       }},
      {"monitors", [](const Object&, PhasesSpec*) { return absl::OkStatus(); },
       [](const PhasesSpec& s, OrderedJson& j) {
         OrderedJson& list = j["monitors"] = OrderedJson::array();
         for (const PressureMonitor& m : s.monitors)
           list.push_back(WriteFields(MonitorFields(), m));
       }},
  };
}

// The phases section: its fields, the drained boundaries (each on a grid
// line that a region reaches) and the pressure monitors (inside a region).
absl::Status ParsePhases(const Json& j, const std::string& ptr, const GridLines& lines,
                         const std::vector<MaterialRegion>& regions, PhasesSpec* phases) {
  phases->saturated = true;
  ASSIGN_OR_RETURN(Object o, ReadFields(j, ptr, PhasesFields(), phases));
  RETURN_IF_ERROR(ParseList(
      o, "drained", Need::kOptional, "drained boundary", &phases->drained,
      [&](const Json& e, const std::string& at, size_t, DrainedBoundary* d) {
        RETURN_IF_ERROR(ReadFields(e, at, DrainedFields(&lines), d).status());
        if (!(d->from < d->to)) {
          return Bad(Child(at, "to"), "must be > from = ", Num(d->from), " m, got ", Num(d->to));
        }
        const int along = 1 - d->axis;
        for (const MaterialRegion& r : regions) {
          if (d->position >= r.lower[d->axis] && d->position <= r.upper[d->axis] &&
              std::max(d->from, r.lower[along]) <= std::min(d->to, r.upper[along])) {
            return absl::OkStatus();
          }
        }
        return Bad(Child(at, "position"), "no region reaches the line ", kAxisName[d->axis], " = ",
                   Num(d->position), " m: a drained boundary must touch the soil");
      }));
  if (phases->free_surface_beside_light_nodes && !phases->drained_free_surface) {
    return Bad(o.At("free_surface_beside_light_nodes"),
               "needs drained_free_surface: it widens the free surface that one drains");
  }
  if (phases->drained.empty() && !phases->drained_free_surface) {
    return Bad(o.At("drained"),
               "a saturated case needs at least one drained boundary (or drained_free_surface): "
               "the pore pressure is otherwise undetermined");
  }
  return ParseList(o, "monitors", Need::kOptional, "monitor", &phases->monitors,
                   [&](const Json& e, const std::string& at, size_t, PressureMonitor* m) {
                     RETURN_IF_ERROR(ReadFields(e, at, MonitorFields(), m).status());
                     for (const MaterialRegion& r : regions) {
                       if ((m->position.array() >= r.lower.array()).all() &&
                           (m->position.array() <= r.upper.array()).all()) {
                         return absl::OkStatus();
                       }
                     }
                     return Bad(Child(at, "position"), "(", Num(m->position.x()), ", ",
                                Num(m->position.y()), ") m is in no region");
                   });
}

// Tracks the path during parsing to report duplicate keys, which
// nlohmann::json would otherwise resolve silently to the last value.
class DuplicateKeys {
 public:
  bool operator()(int /*depth*/, Json::parse_event_t event, Json& parsed) {
    switch (event) {
      case Json::parse_event_t::object_start:
        frames_.emplace_back().object = true;
        break;
      case Json::parse_event_t::array_start:
        frames_.emplace_back();
        break;
      case Json::parse_event_t::key:
        frames_.back().key = parsed.get<std::string>();
        if (!frames_.back().keys.insert(frames_.back().key).second && first_.empty()) {
          first_ = Pointer();
        }
        break;
      case Json::parse_event_t::value:
        if (!frames_.empty() && !frames_.back().object) ++frames_.back().index;
        break;
      case Json::parse_event_t::object_end:
      case Json::parse_event_t::array_end:
        frames_.pop_back();
        if (!frames_.empty() && !frames_.back().object) ++frames_.back().index;
        break;
    }
    return true;
  }
  // The pointer of the first duplicate key, empty when none.
  const std::string& first() const { return first_; }

 private:
  struct Frame {
    bool object = false;
    std::set<std::string> keys;
    std::string key;
    size_t index = 0;
  };
  std::string Pointer() const {
    std::string ptr;
    for (const Frame& f : frames_) ptr = f.object ? Child(ptr, f.key) : Child(ptr, f.index);
    return ptr;
  }
  std::vector<Frame> frames_;
  std::string first_;
};

// "line L, column C" of the character at `index` (0-based) in `text`.
std::string Position(absl::string_view text, size_t index) {
  index = std::min(index, text.size());
  const size_t newline = text.rfind('\n', index == 0 ? 0 : index - 1);
  const size_t line_start =
      newline == absl::string_view::npos || newline >= index ? 0 : newline + 1;
  const size_t line = 1 + std::count(text.begin(), text.begin() + index, '\n');
  return absl::StrCat("line ", line, ", column ", index - line_start + 1);
}

// "line L, column C: <message>" from a parser exception.
absl::Status SyntaxError(const Json::exception& e, absl::string_view text) {
  absl::string_view what = e.what();
  if (const auto* parse = dynamic_cast<const Json::parse_error*>(&e)) {
    // nlohmann stops one character past the culprit, often past a newline
    // (its own "line 3, column 0"): point at the last non-blank character.
    size_t index = std::min<size_t>(parse->byte, text.size());
    if (index > 0) --index;
    while (index > 0 && index < text.size() &&
           std::isspace(static_cast<unsigned char>(text[index]))) {
      --index;
    }
    if (size_t at = what.find(", column "); at != absl::string_view::npos) {
      if (size_t colon = what.find(": ", at); colon != absl::string_view::npos) {
        what = what.substr(colon + 2);
      }
    }
    return absl::InvalidArgumentError(absl::StrCat(Position(text, index), ": ", what));
  }
  // Other exceptions (e.g. "number overflow parsing '1e400'") carry no
  // position: find the quoted token in the text.
  if (size_t bracket = what.find("] "); bracket != absl::string_view::npos) {
    what = what.substr(bracket + 2);
  }
  const size_t open = what.find('\'');
  const size_t close = what.rfind('\'');
  if (open != absl::string_view::npos && close > open + 1) {
    const size_t index = text.find(what.substr(open + 1, close - open - 1));
    if (index != absl::string_view::npos) {
      return absl::InvalidArgumentError(absl::StrCat(Position(text, index), ": ", what));
    }
  }
  return absl::InvalidArgumentError(what);
}

// ---------------------------------------------------------------- writing

std::string Dump(const OrderedJson& j) {
  return j.dump(-1, ' ', false, OrderedJson::error_handler_t::replace);
}

// Two-space indented JSON like dump(2), but arrays of scalars ([x, y],
// [t, vx, vy]) stay on one line, so the output reads like a hand-written case.
void Write(const OrderedJson& j, int indent, std::string* out) {
  const std::string inner(indent + 2, ' ');
  if (j.is_object() && !j.empty()) {
    absl::StrAppend(out, "{\n");
    size_t i = 0;
    for (const auto& [key, value] : j.items()) {
      absl::StrAppend(out, inner, Dump(key), ": ");
      Write(value, indent + 2, out);
      absl::StrAppend(out, ++i < j.size() ? ",\n" : "\n");
    }
    absl::StrAppend(out, std::string(indent, ' '), "}");
  } else if (j.is_array() && !j.empty() &&
             std::any_of(j.begin(), j.end(), [](const OrderedJson& e) {
               return e.is_structured() && !(e.is_array() && e.empty());
             })) {
    absl::StrAppend(out, "[\n");
    for (size_t i = 0; i < j.size(); ++i) {
      absl::StrAppend(out, inner);
      Write(j[i], indent + 2, out);
      absl::StrAppend(out, i + 1 < j.size() ? ",\n" : "\n");
    }
    absl::StrAppend(out, std::string(indent, ' '), "]");
  } else if (j.is_array()) {
    std::vector<std::string> items;
    for (const OrderedJson& e : j) items.push_back(Dump(e));
    absl::StrAppend(out, "[", absl::StrJoin(items, ", "), "]");
  } else {
    absl::StrAppend(out, Dump(j));
  }
}

}  // namespace

CaseSize EstimateSize(const CaseSpec& spec) {
  CaseSize size;
  size.nodes = (static_cast<std::int64_t>(spec.grid.nx) + 1) * (spec.grid.ny + 1);
  std::map<std::string, double> rve_bytes;
  for (const TemplateSpec& t : spec.templates) {
    // A prepared template's disc count is known; a file's is not read here.
    absl::StatusOr<dem::ParameterSet> set = dem::FindParameterSet(t.parameter_set);
    int discs = t.file.empty() && set.ok() ? set->preparation.num_particles : 400;
    if (t.file.empty() && t.particles > 0) discs = t.particles;
    rve_bytes[t.name] = kRveBytesPerDisc * discs;
  }
  double bytes = kBytesPerNode * static_cast<double>(size.nodes);
  for (const MaterialRegion& r : spec.regions) {
    double points = static_cast<double>(r.points_per_cell_side) * r.points_per_cell_side;
    for (int d = 0; d < 2; ++d) {
      points *= std::max(0.0, std::round((r.upper[d] - r.lower[d]) / spec.grid.cell_size));
    }
    size.points += static_cast<std::int64_t>(points);
    bytes += points * (kBytesPerPoint + rve_bytes[r.rve_template]);
  }
  size.bytes = bytes;
  return size;
}

absl::StatusOr<CaseOverride> ParseOverride(absl::string_view text) {
  const std::size_t eq = text.find('=');
  if (eq == absl::string_view::npos || eq == 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "--set needs PATH=VALUE (e.g. --set=/rve/min_steps=4 or --set=rve.min_steps=4), got '",
        text, "'"));
  }
  CaseOverride o;
  const absl::string_view path = text.substr(0, eq);
  o.value = std::string(text.substr(eq + 1));
  if (absl::StartsWith(path, "/")) {
    o.pointer = std::string(path);
  } else {
    for (absl::string_view token : absl::StrSplit(path, '.')) {
      o.pointer = Child(o.pointer, token);
    }
  }
  return o;
}

namespace {

absl::Status ApplyOverride(const CaseOverride& o, Json& doc) {
  const std::string what = absl::StrCat("--set ", o.pointer);
  Json::json_pointer pointer;
  try {
    pointer = Json::json_pointer(o.pointer);
  } catch (const Json::exception& e) {
    return absl::InvalidArgumentError(absl::StrCat(what, ": not a JSON pointer (", e.what(), ")"));
  }
  if (pointer.empty())
    return absl::InvalidArgumentError(absl::StrCat(what, ": names the whole case"));
  const Json::json_pointer parent = pointer.parent_pointer();
  const std::string parent_text = parent.empty() ? "the case" : parent.to_string();
  if (!doc.contains(parent)) {
    return absl::InvalidArgumentError(absl::StrCat(what, ": ", parent_text, " is not in the case"));
  }
  Json& container = doc[parent];
  if (container.is_array()) {
    // Only existing elements: an override changes a case, it does not grow lists.
    if (!doc.contains(pointer)) {
      return absl::InvalidArgumentError(
          absl::StrCat(what, ": ", parent_text, " has ", container.size(), " elements"));
    }
  } else if (!container.is_object()) {
    return absl::InvalidArgumentError(
        absl::StrCat(what, ": ", parent_text, " is not an object or array"));
  }
  Json value;
  try {
    value = Json::parse(o.value);
  } catch (const Json::exception&) {
    value = o.value;  // a bare word: a string
  }
  doc[pointer] = std::move(value);
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<CaseSpec> ParseCase(absl::string_view json_text, const std::string& base_dir) {
  return ParseCase(json_text, base_dir, {});
}

absl::string_view FBarName(FBar f) { return f == FBar::kNodal ? "nodal" : "none"; }

absl::StatusOr<FBar> FBarFromName(absl::string_view name) {
  for (const auto& [n, value] : kFBars) {
    if (n == name) return value;
  }
  return absl::InvalidArgumentError(
      absl::StrCat("must be one of ", Choices(kFBars), ", got ", Quote(name)));
}

absl::StatusOr<CaseSpec> ParseCase(absl::string_view json_text, const std::string& base_dir,
                                   std::span<const CaseOverride> overrides) {
  Json doc;
  DuplicateKeys duplicates;
  try {
    doc = Json::parse(json_text.begin(), json_text.end(), std::ref(duplicates));
  } catch (const Json::exception& e) {
    return SyntaxError(e, json_text);
  }
  if (!duplicates.first().empty()) {
    return Bad(duplicates.first(), "duplicate key (an object holds each key once)");
  }
  for (const CaseOverride& o : overrides) RETURN_IF_ERROR(ApplyOverride(o, doc));

  ASSIGN_OR_RETURN(Object root, Object::Open(doc, "",
                                             {"name", "description", "expected_runtime_s", "grid",
                                              "solver", "templates", "regions", "walls", "bodies",
                                              "tractions", "rve", "phases", "output"}));
  CaseSpec spec;
  RETURN_IF_ERROR(GetString(root, "name", Need::kOptional, false, &spec.name));
  RETURN_IF_ERROR(GetString(root, "description", Need::kOptional, false, &spec.description));
  RETURN_IF_ERROR(GetNumber(root, "expected_runtime_s", Need::kOptional, kNonNegative,
                            &spec.expected_runtime_s));

  const Json* grid = root.Get("grid");
  if (grid == nullptr) return root.Missing("grid");
  RETURN_IF_ERROR(ParseGrid(*grid, root.At("grid"), &spec.grid));
  const GridLines lines(spec.grid);

  const Json* solver = root.Get("solver");
  if (solver == nullptr) return root.Missing("solver");
  RETURN_IF_ERROR(ParseSolver(*solver, root.At("solver"), &spec.solver));

  RETURN_IF_ERROR(ParseList(root, "templates", Need::kRequired, "template", &spec.templates,
                            [&](const Json& j, const std::string& ptr, size_t, TemplateSpec* t) {
                              return ParseTemplate(j, ptr, base_dir, t);
                            }));

  std::vector<CellBox> boxes;
  RETURN_IF_ERROR(ParseList(root, "regions", Need::kRequired, "region", &spec.regions,
                            [&](const Json& j, const std::string& ptr, size_t, MaterialRegion* r) {
                              boxes.emplace_back();
                              return ParseRegion(j, ptr, lines, spec.solver, spec.templates, r,
                                                 &boxes.back());
                            }));
  RETURN_IF_ERROR(CheckOverlaps(spec.regions, boxes, root.At("regions")));

  RETURN_IF_ERROR(ParseList(root, "walls", Need::kOptional, "wall", &spec.walls,
                            [&](const Json& j, const std::string& ptr, size_t, Wall* w) {
                              return ParseWall(j, ptr, lines, w);
                            }));
  RETURN_IF_ERROR(ParseList(root, "bodies", Need::kOptional, "body", &spec.bodies,
                            [&](const Json& j, const std::string& ptr, size_t, RigidBody* b) {
                              return ParseBody(j, ptr, b);
                            }));
  RETURN_IF_ERROR(ParseList(root, "tractions", Need::kOptional, "traction", &spec.tractions,
                            [&](const Json& j, const std::string& ptr, size_t, SurfaceTraction* t) {
                              return ParseTraction(j, ptr, spec.regions, boxes, root.At("regions"),
                                                   t);
                            }));

  if (const Json* rve = root.Get("rve")) {
    RETURN_IF_ERROR(ParseRve(*rve, root.At("rve"), &spec.rve));
  }
  if (const Json* phases = root.Get("phases")) {
    // A wall shaken on its fixed grid line draws the soil off the line by
    // the shake's displacement, which the free-surface test of the water
    // then takes for a drained face: refused for the box's frame.
    for (std::size_t w = 0; w < spec.walls.size(); ++w) {
      if (IsShaken(spec.walls[w])) {
        return Bad(absl::StrCat(root.At("walls"), "/", w, "/shaking_amplitude"),
                   "a saturated case shakes its whole box (solver.shaking_amplitude and "
                   "solver.shaking_frequency), not single walls");
      }
    }
    RETURN_IF_ERROR(ParsePhases(*phases, root.At("phases"), lines, spec.regions, &spec.phases));
    // The two-phase step's porosity, drag and pressure need every point on
    // the grid.
    if (spec.phases.saturated && spec.solver.lost_points == LostPointPolicy::kDrop) {
      return Bad(root.At("solver") + "/lost_points", "\"drop\" is for dry cases only");
    }
    // Scaled inertia would change the drag's and the pressure's time scales.
    if (spec.phases.saturated && spec.solver.mass_scale != 1.0) {
      return Bad(root.At("solver") + "/mass_scale", "mass scaling is for dry cases only");
    }
    // The water's mass balance takes its porosity from the RVE's void ratio.
    if (spec.phases.saturated && spec.rve.max_void_ratio > 0.0) {
      return Bad(root.At("rve") + "/max_void_ratio", "a void-ratio cap is for dry cases only");
    }
    // The water's mass balance follows each point's own strain.
    if (spec.phases.saturated && spec.solver.nonlocal_radius > 0.0) {
      return Bad(root.At("solver") + "/nonlocal_radius", "a nonlocal strain is for dry cases only");
    }
    // The two-phase step's pressure solve is set up for one Δt.
    if (spec.phases.saturated && spec.solver.time_step_update_every > 0) {
      return Bad(root.At("solver") + "/time_step_update_every",
                 "an updated time step is for dry cases only");
    }
    // A drained free surface holds p = 0, so water at rest fills the soil to
    // its top. A table above it (free water over the soil, not modelled)
    // started a pressure shock: 10 m over cyclic-shaking-medium-ci's 1 m
    // box gave 1.8 J of kinetic energy in the first step against 0.04 J.
    if (const double table = spec.phases.water_table; spec.phases.drained_free_surface &&
                                                      spec.solver.gravity.norm() > 0.0 &&
                                                      std::isfinite(table)) {
      double top = -kInf;  // m
      for (const MaterialRegion& r : spec.regions) top = std::max(top, r.upper.y());
      if (table > top + 1e-9 * std::max(1.0, std::abs(top))) {
        return Bad(root.At("phases") + "/water_table", "y = ", Num(table),
                   " m lies above the soil's top, y = ", Num(top),
                   " m: free water over the soil is not modelled (the drained free surface "
                   "holds p = 0); put the table at the top");
      }
    }
  }
  if (const double radius = spec.solver.nonlocal_radius; radius > 0.0) {
    const std::string at = root.At("solver") + "/nonlocal_radius";
    // Each averages the strain its own way; one at a time keeps either's
    // energy balance exact.
    if (spec.solver.f_bar != FBar::kNone) return Bad(at, "not together with solver.f_bar");
    // Below a tenth of a cell no point has a neighbour within it; beyond
    // 8 cells the averaging would span most small domains and cost O(n·64²).
    const double h = spec.grid.cell_size;
    if (radius < 0.1 * h || radius > 8.0 * h) {
      return Bad(at, absl::StrFormat("%.6g m must be 0 (off) or between 0.1 and 8 cells (%.6g to "
                                     "%.6g m for cells of %.6g m)",
                                     radius, 0.1 * h, 8.0 * h, h));
    }
  }
  if (const Json* output = root.Get("output")) {
    RETURN_IF_ERROR(ParseOutput(*output, root.At("output"), spec.bodies, base_dir, &spec.output));
  }
  // Refused here rather than as std::bad_alloc an hour into setting up.
  if (const CaseSize size = EstimateSize(spec); size.bytes > kMaxCaseBytes) {
    return Bad("/grid",
               absl::StrFormat(
                   "the case needs about %.1f GiB (%d grid nodes, %d material points "
                   "with their RVEs), more than the limit of %.0f GiB: use a coarser grid "
                   "or smaller regions",
                   size.bytes / (1 << 30), size.nodes, size.points, kMaxCaseBytes / (1 << 30)));
  }
  return spec;
}

absl::StatusOr<CaseSpec> LoadCase(const std::string& path,
                                  std::span<const CaseOverride> overrides) {
  ASSIGN_OR_RETURN(std::string text, ReadTextFile(path, "case file"));
  const std::filesystem::path file(path);
  const std::string dir = file.has_parent_path() ? file.parent_path().string() : ".";
  absl::StatusOr<CaseSpec> spec = ParseCase(text, dir, overrides);
  if (!spec.ok()) {
    return absl::Status(spec.status().code(), absl::StrCat(path, ": ", spec.status().message()));
  }
  if (spec->name.empty()) spec->name = file.stem().string();
  return spec;
}

std::string ToJson(const CaseSpec& spec) {
  OrderedJson doc;
  doc["name"] = spec.name;
  doc["description"] = spec.description;
  doc["expected_runtime_s"] = spec.expected_runtime_s;

  doc["grid"] = WriteFields(GridFields(), spec.grid);
  doc["solver"] = WriteFields(SolverFields(), spec.solver);

  OrderedJson& templates = doc["templates"] = OrderedJson::array();
  for (const TemplateSpec& t : spec.templates) {
    templates.push_back(WriteFields(TemplateFields(""), t));
  }

  OrderedJson& regions = doc["regions"] = OrderedJson::array();
  for (const MaterialRegion& r : spec.regions) regions.push_back(WriteFields(RegionFields({}), r));

  OrderedJson& walls = doc["walls"] = OrderedJson::array();
  for (const Wall& w : spec.walls) walls.push_back(WriteFields(WallFields(nullptr), w));

  OrderedJson& bodies = doc["bodies"] = OrderedJson::array();
  for (const RigidBody& b : spec.bodies) bodies.push_back(WriteFields(BodyFields(), b));

  OrderedJson& tractions = doc["tractions"] = OrderedJson::array();
  for (const SurfaceTraction& t : spec.tractions) {
    tractions.push_back(WriteFields(TractionFields(nullptr), t));
  }

  doc["rve"] = WriteFields(RveFields(), spec.rve);
  if (spec.phases.saturated) doc["phases"] = WriteFields(PhasesFields(), spec.phases);
  doc["output"] = WriteFields(OutputFields(nullptr, ""), spec.output);
  std::string out;
  Write(doc, 0, &out);
  return out;
}

}  // namespace rvehub::mpm
