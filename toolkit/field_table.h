// Reading JSON input files into plain structs, with every error naming the
// JSON pointer of the bad value (json_pointer.h), and writing the structs
// back as canonical JSON: readers of single values, an object reader that
// refuses unknown keys, and field tables (Field<S>) that hold each key of a
// section once, for both directions. Knows nothing of any client's model.
//
// Every reader returns OkStatus or InvalidArgument "<pointer>: <message>";
// the message shapes are stated at each reader. A reader leaves its output
// untouched when it fails, and a Get* reader leaves it untouched when an
// optional key is absent (so the struct's default stands).
#ifndef RVEHUB_TOOLKIT_FIELD_TABLE_H_
#define RVEHUB_TOOLKIT_FIELD_TABLE_H_

#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <initializer_list>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_join.h"
#include "absl/strings/string_view.h"
#include "rve_server/common/status_macros.h"
#include "toolkit/json_pointer.h"

namespace rvehub::fields {

inline constexpr double kInf = std::numeric_limits<double>::infinity();

enum class Need { kOptional, kRequired };

// A JSON object at `ptr` whose keys are all in an allowed list.
class Object {
 public:
  // Not an object: "must be an object, got <Got>". A key not in `keys`:
  // "<ptr>/<key>: unknown key (did you mean \"<k>\"? keys here: a, b, c)",
  // the suggestion only for an allowed key longer than 3 characters within
  // edit distance 2 (the first nearest in `keys`' order), else
  // "unknown key (keys here: a, b, c)". Unknown keys are checked in the
  // document's order (nlohmann::json: alphabetical).
  static absl::StatusOr<Object> Open(const Json& j, std::string ptr,
                                     const std::vector<absl::string_view>& keys);

  const std::string& ptr() const { return ptr_; }
  // The pointer of `key` in this object.
  std::string At(absl::string_view key) const { return Child(ptr_, key); }
  // The value of `key`, null when absent.
  const Json* Get(absl::string_view key) const {
    auto it = j_->find(std::string(key));
    return it == j_->end() ? nullptr : &*it;
  }
  bool Has(absl::string_view key) const { return Get(key) != nullptr; }
  // "<ptr>/<key>: required key is missing".
  absl::Status Missing(absl::string_view key) const {
    return Bad(At(key), "required key is missing");
  }

 private:
  Object(const Json& j, std::string ptr) : j_(&j), ptr_(std::move(ptr)) {}
  const Json* j_;
  std::string ptr_;
};

// Every number read is at most 1e12 in magnitude (fields with a physical
// range have tighter bounds): products of a few input values then stay far
// from overflow.
inline constexpr double kMaxMagnitude = 1e12;
// And a number that must be > 0 is at least 1e-12: a positive 1e-308 passed
// as positive, then its quotients overflowed to NaN mid-run.
inline constexpr double kMinPositive = 1e-12;

// An allowed interval of a real number, open or closed at either end.
struct Range {
  double lo = -kInf;
  double hi = kInf;
  bool lo_open = false;
  bool hi_open = false;

  // (0, hi]: then also >= kMinPositive.
  bool MustBePositive() const { return lo == 0.0 && lo_open; }
  bool Contains(double x) const {
    if (MustBePositive() && x < kMinPositive) return false;
    return (lo_open ? x > lo : x >= lo) && (hi_open ? x < hi : x <= hi);
  }
  // What is wrong with x, the message before ", got <x>": "must be at most
  // 1e+12 in magnitude" (a bound of ±kMaxMagnitude broken), "must be at least
  // 1e-12 (the smallest positive value a case takes)", "must be a finite
  // number" (no other bound), "must be > lo", ">= lo", "< hi", "<= hi", or
  // "must be in [lo, hi)" with "(" or "[", ")" or "]" as the ends are open
  // or closed. Bounds of ±kMaxMagnitude are not named unless broken.
  std::string Rule(double x) const;
};
inline constexpr Range kAny{-kMaxMagnitude, kMaxMagnitude, false, false};
inline constexpr Range kPositive{0.0, kMaxMagnitude, true, false};
inline constexpr Range kNonNegative{0.0, kMaxMagnitude, false, false};
inline constexpr Range kUnit{0.0, 1.0, false, false};

// A JSON number in `range`: "must be a number, got <Got>", or
// "<range.Rule(x)>, got <Num(x)>".
absl::Status ReadNumber(const Json& v, absl::string_view ptr, const Range& range, double* out);

// An integer in [lo, hi], from an integral JSON number (floats such as 1e3
// too): "must be an integer in lo..hi, got <x>", or "must be an integer >=
// lo, got <x>" when hi is the int64 maximum; <x> is <Got> for a non-number.
absl::Status ReadInteger(const Json& v, absl::string_view ptr, std::int64_t lo, std::int64_t hi,
                         std::int64_t* out);
// ReadInteger into an int.
absl::Status ReadInt(const Json& v, absl::string_view ptr, int lo, int hi, int* out);

// Any uint64 (a random seed), integral floats such as 1e3 too:
// "must be an integer in 0..18446744073709551615, got <Got>".
absl::Status ReadSeed(const Json& v, absl::string_view ptr, std::uint64_t* out);

// "must be a string, got <Got>"; with `non_empty`, "must be a non-empty
// string" for "".
absl::Status ReadString(const Json& v, absl::string_view ptr, bool non_empty, std::string* out);

// Names end up in file and column names and in ids on the RVE servers
// (after a run id of up to 88 characters and a '.', within their 128), so
// they are short and of a portable alphabet.
inline constexpr std::size_t kMaxNameLength = 32;

// A non-empty string of at most kMaxNameLength letters, digits, '_', '-' and
// '.': ReadString's messages, "names have at most 32 characters, got <n>", or
// "names use letters, digits, '_', '-' and '.' only, got \"<name>\"".
absl::Status ReadName(const Json& v, absl::string_view ptr, std::string* out);

// An enumeration's names and values, in the order messages list them; a
// value may have several names (aliases). A Table held by a field must have
// static storage (a namespace-scope constexpr or const Table).
template <typename T>
using Table = std::initializer_list<std::pair<absl::string_view, T>>;

// "a, b, c": the table's names.
template <typename T>
std::string Choices(Table<T> table) {
  std::vector<absl::string_view> names;
  for (const auto& [name, value] : table) names.push_back(name);
  return absl::StrJoin(names, ", ");
}

// One of the table's names: "must be a string (a, b, c), got <Got>", or
// "unknown <what> \"<s>\" (a, b, c)".
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

// [x, y], each a ReadNumber in `range` (its messages at "<ptr>/0", "<ptr>/1"):
// "must be an array of 2 numbers [x, y], got <Got>".
absl::Status ReadVec2(const Json& v, absl::string_view ptr, const Range& range,
                      Eigen::Vector2d* out);

// An array of rows [t, v...] of `width` numbers (at most 3; `shape` names
// them in messages, e.g. "[t, vx, vy] (s, m/s, m/s)"), times >= 0 and
// increasing strictly, values kAny; the unused entries of a row are 0.
// Messages: "must be an array of <shape>, got <Got>" ("must be a non-empty
// array of ..." with `non_empty`), at "<ptr>/<i>": "must be an array of
// <width> numbers <shape>, got <Got>", at "<ptr>/<i>/0": "times must
// increase strictly, got <t> s after <t0> s", and ReadNumber's.
absl::Status ReadTimeRows(const Json& j, const std::string& ptr, size_t width,
                          absl::string_view shape, bool non_empty,
                          std::vector<std::array<double, 3>>* rows);

// The readers above for the value of `key` in `o`. An absent key is
// "<ptr>/<key>: required key is missing" with Need::kRequired; otherwise
// the output is left untouched.
absl::Status GetNumber(const Object& o, absl::string_view key, Need need, const Range& range,
                       double* out);
// Always optional.
absl::Status GetInteger(const Object& o, absl::string_view key, std::int64_t lo, std::int64_t hi,
                        std::int64_t* out);
absl::Status GetString(const Object& o, absl::string_view key, Need need, bool non_empty,
                       std::string* out);
// The required key "name", ReadName.
absl::Status GetName(const Object& o, std::string* out);
template <typename T>
absl::Status GetEnum(const Object& o, absl::string_view key, Need need, absl::string_view what,
                     Table<T> table, T* out) {
  const Json* v = o.Get(key);
  if (v == nullptr) return need == Need::kRequired ? o.Missing(key) : absl::OkStatus();
  return ReadEnum(*v, o.At(key), what, table, out);
}
absl::Status GetVec2(const Object& o, absl::string_view key, Need need, const Range& range,
                     Eigen::Vector2d* out);

// The elements of an optional array, appended to `out`; with Need::kRequired
// present and non-empty. Messages: "must be an array, got <Got>", "must not
// be empty".
absl::Status GetArray(const Object& o, absl::string_view key, Need need,
                      std::vector<const Json*>* out);

// A file named by the required non-empty string `key`, relative to
// `base_dir` unless absolute, as an absolute normal path (so what was read
// does not depend on the working directory); it must be a regular file:
// "no such file \"<path>\"".
absl::Status GetFile(const Object& o, absl::string_view key, const std::string& base_dir,
                     std::string* out);

// "<ptr>/<key>: <why>" when `key` is present.
absl::Status Forbid(const Object& o, absl::string_view key, absl::string_view why);

// Names must be unique within a list at `ptr`: "<ptr>/<i>/name: duplicate
// <what> name \"<name>\" (also <ptr>/<j>)" for the first repeat.
absl::Status CheckUnique(const std::vector<std::string>& names, absl::string_view ptr,
                         absl::string_view what);

// The `name` members of `items`.
template <typename T>
std::vector<std::string> NamesOf(const std::vector<T>& items) {
  std::vector<std::string> names;
  for (const T& item : items) names.push_back(item.name);
  return names;
}

// A list of named objects at `key` (GetArray): `items` is resized to the
// list (an absent optional list: empty), each element read by
// parse(element, pointer, index, &item) in order, then the names checked
// with CheckUnique.
template <typename T, typename F>
absl::Status GetList(const Object& o, absl::string_view key, Need need, absl::string_view what,
                     std::vector<T>* items, F parse) {
  std::vector<const Json*> elements;
  RETURN_IF_ERROR(GetArray(o, key, need, &elements));
  const std::string ptr = o.At(key);
  items->resize(elements.size());
  for (size_t i = 0; i < elements.size(); ++i) {
    RETURN_IF_ERROR(parse(*elements[i], Child(ptr, i), i, &(*items)[i]));
  }
  return CheckUnique(NamesOf(*items), ptr, what);
}

// ---------------------------------------------------------------- field tables

// One key of a section (a struct S), once: how it is read (with its
// validation) and how the canonical writer writes it back. A section's
// table lists its keys in order; ReadFields reads them in that order (so a
// rule may look at keys read before it), WriteFields writes them so.
template <typename S>
struct Field {
  absl::string_view key;
  std::function<absl::Status(const Object&, S*)> read;
  // Writes the key into `j`, or nothing where the struct does not use it.
  std::function<void(const S&, OrderedJson&)> write;
};
template <typename S>
using Fields = std::vector<Field<S>>;

// [x, y].
OrderedJson Vec2Json(const Eigen::Vector2d& v);

// A number (GetNumber), always written.
template <typename S>
Field<S> NumberField(absl::string_view key, double S::*m, Need need, Range range) {
  return {key, [=](const Object& o, S* s) { return GetNumber(o, key, need, range, &(s->*m)); },
          [=](const S& s, OrderedJson& j) { j[std::string(key)] = s.*m; }};
}

// A number that is infinite (never, unbounded) unless given (GetNumber);
// written only when finite.
template <typename S>
Field<S> OptionalFiniteField(absl::string_view key, double S::*m, Range range) {
  return {
      key,
      [=](const Object& o, S* s) { return GetNumber(o, key, Need::kOptional, range, &(s->*m)); },
      [=](const S& s, OrderedJson& j) {
        if (std::isfinite(s.*m)) j[std::string(key)] = s.*m;
      }};
}

// [x, y] (GetVec2), always written.
template <typename S>
Field<S> Vec2Field(absl::string_view key, Eigen::Vector2d S::*m, Need need, Range range) {
  return {key, [=](const Object& o, S* s) { return GetVec2(o, key, need, range, &(s->*m)); },
          [=](const S& s, OrderedJson& j) { j[std::string(key)] = Vec2Json(s.*m); }};
}

// An optional integer in [lo, hi] (GetInteger), always written.
template <typename S>
Field<S> IntegerField(absl::string_view key, std::int64_t S::*m, std::int64_t lo, std::int64_t hi) {
  return {key, [=](const Object& o, S* s) { return GetInteger(o, key, lo, hi, &(s->*m)); },
          [=](const S& s, OrderedJson& j) { j[std::string(key)] = s.*m; }};
}

// A string (GetString), always written.
template <typename S>
Field<S> TextField(absl::string_view key, std::string S::*m, Need need, bool non_empty) {
  return {key, [=](const Object& o, S* s) { return GetString(o, key, need, non_empty, &(s->*m)); },
          [=](const S& s, OrderedJson& j) { j[std::string(key)] = s.*m; }};
}

// A flag, false when absent ("must be true or false, got <Got>"); written
// only when true.
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

// The required "name" of S::name (GetName).
template <typename S>
Field<S> NameField() {
  return {"name", [](const Object& o, S* s) { return GetName(o, &s->name); },
          [](const S& s, OrderedJson& j) { j["name"] = s.name; }};
}

// An enumeration (GetEnum): read by `table` (aliases allowed), written as
// name(value). `table` must have static storage (a constexpr Table).
template <typename S, typename T>
Field<S> EnumField(absl::string_view key, T S::*m, Need need, absl::string_view what,
                   Table<T> table, absl::string_view (*name)(T)) {
  return {key, [=](const Object& o, S* s) { return GetEnum(o, key, need, what, table, &(s->*m)); },
          [=](const S& s, OrderedJson& j) { j[std::string(key)] = name(s.*m); }};
}

// `field` only where `applies` holds for what was read before it; elsewhere
// the key is refused (Forbid: "<ptr>/<key>: <why>") and not written.
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

// Opens the section's object (Object::Open with the table's keys: unknown
// keys refused) and reads every field in order, stopping at the first error.
// The object is returned for checks across fields.
template <typename S>
absl::StatusOr<Object> ReadFields(const Json& j, const std::string& ptr, const Fields<S>& fields,
                                  S* s) {
  ASSIGN_OR_RETURN(Object o, Object::Open(j, ptr, KeysOf(fields)));
  for (const Field<S>& f : fields) RETURN_IF_ERROR(f.read(o, s));
  return o;
}

// The section as a JSON object, its keys in the table's order.
template <typename S>
OrderedJson WriteFields(const Fields<S>& fields, const S& s) {
  OrderedJson j = OrderedJson::object();
  for (const Field<S>& f : fields) f.write(s, j);
  return j;
}

}  // namespace rvehub::fields

#endif  // RVEHUB_TOOLKIT_FIELD_TABLE_H_
