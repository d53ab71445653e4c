// The field-table reader (toolkit/): each reader's accepted values and its
// exact messages, the object reader's unknown-key suggestions, field tables
// read and written back, and the JSON document (positions of syntax errors,
// duplicate keys, --set overrides, the canonical layout). A toy struct
// stands in for a client's model.
#include "toolkit/field_table.h"

#include <unistd.h>

#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "gtest/gtest.h"
#include "toolkit/json_document.h"
#include "toolkit/json_pointer.h"

namespace rvehub::fields {
namespace {

namespace fs = std::filesystem;

// The message of a status that must be InvalidArgument.
std::string Message(const absl::Status& status) {
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
  return std::string(status.message());
}

TEST(FieldTableMessages, PointersEscapeTheirTokens) {
  EXPECT_EQ(Escape("a/b~c"), "a~1b~0c");
  EXPECT_EQ(Child("/grid", "cell/size~"), "/grid/cell~1size~0");
  EXPECT_EQ(Child("/regions", size_t{3}), "/regions/3");
  EXPECT_EQ(Child("", "grid"), "/grid");
}

TEST(FieldTableMessages, BadNamesThePointerOrTheDocument) {
  EXPECT_EQ(Message(Bad("/a/0", "must be ", 2, ", got ", Num(0.5))), "/a/0: must be 2, got 0.5");
  EXPECT_EQ(Message(Bad("", "must be an object")), "(document): must be an object");
}

TEST(FieldTableMessages, NumbersQuotesAndGot) {
  EXPECT_EQ(Num(0.1 + 0.2), "0.3");  // 10 significant digits
  EXPECT_EQ(Num(0.30001), "0.30001");
  EXPECT_EQ(Num(1e12), "1e+12");
  EXPECT_EQ(Quote("x"), "\"x\"");
  EXPECT_EQ(Got(Json()), "null");
  EXPECT_EQ(Got(Json("abc")), "string \"abc\"");
  EXPECT_EQ(Got(Json::array({1, 2})), "array [1,2]");
  // Long values are cut: 57 characters and "...".
  const std::string got = Got(Json(std::string(100, 'a')));
  EXPECT_EQ(got, absl::StrCat("string \"", std::string(56, 'a'), "..."));
}

TEST(FieldTableObject, AnUnknownKeyIsRefusedWithASuggestion) {
  const Json j = Json::parse(R"({"cell_sise": 0.5})");
  absl::StatusOr<Object> o = Object::Open(j, "/grid", {"origin", "cell_size", "cells"});
  ASSERT_FALSE(o.ok());
  EXPECT_EQ(Message(o.status()),
            "/grid/cell_sise: unknown key (did you mean \"cell_size\"? keys here: origin, "
            "cell_size, cells)");
}

TEST(FieldTableObject, FarOrShortKeysGetNoSuggestion) {
  // Three edits away: no suggestion.
  const Json far = Json::parse(R"({"colour": 1})");
  EXPECT_EQ(Message(Object::Open(far, "", {"name", "cells"}).status()),
            "/colour: unknown key (keys here: name, cells)");
  // One edit from a key of 3 characters or fewer: too many near misses.
  const Json short_key = Json::parse(R"({"tx": 1})");
  EXPECT_EQ(Message(Object::Open(short_key, "/t", {"to", "from"}).status()),
            "/t/tx: unknown key (keys here: to, from)");
  // A key with "/" is escaped in the pointer.
  const Json slash = Json::parse(R"({"a/b": 1})");
  EXPECT_EQ(Message(Object::Open(slash, "/x", {"ab"}).status()),
            "/x/a~1b: unknown key (keys here: ab)");
}

TEST(FieldTableObject, NotAnObjectAndMissingKeys) {
  EXPECT_EQ(Message(Object::Open(Json::array({1}), "/walls/0", {"name"}).status()),
            "/walls/0: must be an object, got array [1]");
  const Json j = Json::parse(R"({"name": "a"})");
  absl::StatusOr<Object> o = Object::Open(j, "/walls/0", {"name", "kind"});
  ASSERT_TRUE(o.ok()) << o.status();
  EXPECT_TRUE(o->Has("name"));
  EXPECT_EQ(o->Get("kind"), nullptr);
  EXPECT_EQ(o->At("kind"), "/walls/0/kind");
  EXPECT_EQ(Message(o->Missing("kind")), "/walls/0/kind: required key is missing");
}

TEST(FieldTableReaders, NumbersOutOfRangeNameTheRule) {
  double x = 7.0;
  EXPECT_EQ(Message(ReadNumber(Json(1.5), "/p", kUnit, &x)), "/p: must be in [0, 1], got 1.5");
  EXPECT_EQ(Message(ReadNumber(Json(0), "/p", Range{0.0, 1.0, true, false}, &x)),
            "/p: must be in (0, 1], got 0");
  EXPECT_EQ(Message(ReadNumber(Json(1), "/p", Range{0.0, 1.0, false, true}, &x)),
            "/p: must be in [0, 1), got 1");
  EXPECT_EQ(Message(ReadNumber(Json(0), "/p", kPositive, &x)), "/p: must be > 0, got 0");
  EXPECT_EQ(Message(ReadNumber(Json(-1), "/p", kNonNegative, &x)), "/p: must be >= 0, got -1");
  EXPECT_EQ(Message(ReadNumber(Json(5), "/p", Range{-kInf, 5.0, false, true}, &x)),
            "/p: must be < 5, got 5");
  EXPECT_EQ(Message(ReadNumber(Json(6), "/p", Range{-kInf, 5.0}, &x)), "/p: must be <= 5, got 6");
  // The generic bounds: magnitude and the smallest positive value.
  EXPECT_EQ(Message(ReadNumber(Json(-1e13), "/p", kAny, &x)),
            "/p: must be at most 1e+12 in magnitude, got -1e+13");
  EXPECT_EQ(Message(ReadNumber(Json(1e13), "/p", kPositive, &x)),
            "/p: must be at most 1e+12 in magnitude, got 1e+13");
  EXPECT_EQ(Message(ReadNumber(Json(1e-13), "/p", kPositive, &x)),
            "/p: must be at least 1e-12 (the smallest positive value a case takes), got 1e-13");
  EXPECT_EQ(Message(ReadNumber(Json("1"), "/p", kAny, &x)),
            "/p: must be a number, got string \"1\"");
  EXPECT_EQ(x, 7.0);  // untouched by every failure
  ASSERT_TRUE(ReadNumber(Json(1e-12), "/p", kPositive, &x).ok());
  EXPECT_EQ(x, 1e-12);
  ASSERT_TRUE(ReadNumber(Json(-1e12), "/p", kAny, &x).ok());
  EXPECT_EQ(x, -1e12);
}

TEST(FieldTableReaders, Integers) {
  std::int64_t n = 5;
  EXPECT_EQ(Message(ReadInteger(Json(4.5), "/n", 1, 8, &n)),
            "/n: must be an integer in 1..8, got 4.5");
  EXPECT_EQ(Message(ReadInteger(Json(9), "/n", 1, 8, &n)), "/n: must be an integer in 1..8, got 9");
  EXPECT_EQ(Message(ReadInteger(Json("x"), "/n", 1, 8, &n)),
            "/n: must be an integer in 1..8, got string \"x\"");
  constexpr std::int64_t kMax = std::numeric_limits<std::int64_t>::max();
  EXPECT_EQ(Message(ReadInteger(Json(-1), "/n", 0, kMax, &n)),
            "/n: must be an integer >= 0, got -1");
  EXPECT_EQ(
      Message(ReadInteger(Json(std::numeric_limits<std::uint64_t>::max()), "/n", 0, kMax, &n)),
      "/n: must be an integer >= 0, got 18446744073709551615");
  EXPECT_EQ(n, 5);
  ASSERT_TRUE(ReadInteger(Json(1e3), "/n", 0, kMax, &n).ok());  // an integral float
  EXPECT_EQ(n, 1000);
  int i = 0;
  ASSERT_TRUE(ReadInt(Json(8), "/i", 1, 8, &i).ok());
  EXPECT_EQ(i, 8);
}

TEST(FieldTableReaders, Seeds) {
  std::uint64_t seed = 0;
  ASSERT_TRUE(ReadSeed(Json(std::numeric_limits<std::uint64_t>::max()), "/s", &seed).ok());
  EXPECT_EQ(seed, std::numeric_limits<std::uint64_t>::max());
  ASSERT_TRUE(ReadSeed(Json(1e3), "/s", &seed).ok());
  EXPECT_EQ(seed, 1000u);
  EXPECT_EQ(Message(ReadSeed(Json(-1), "/s", &seed)),
            "/s: must be an integer in 0..18446744073709551615, got number -1");
  EXPECT_EQ(Message(ReadSeed(Json(1.5), "/s", &seed)),
            "/s: must be an integer in 0..18446744073709551615, got number 1.5");
}

TEST(FieldTableReaders, StringsAndNames) {
  std::string s = "kept";
  EXPECT_EQ(Message(ReadString(Json(3), "/s", false, &s)), "/s: must be a string, got number 3");
  EXPECT_EQ(Message(ReadString(Json(""), "/s", true, &s)), "/s: must be a non-empty string");
  ASSERT_TRUE(ReadString(Json(""), "/s", false, &s).ok());
  EXPECT_EQ(s, "");
  std::string name;
  ASSERT_TRUE(ReadName(Json("soil_1-a.b"), "/n", &name).ok());
  EXPECT_EQ(name, "soil_1-a.b");
  EXPECT_EQ(Message(ReadName(Json("my soil"), "/n", &name)),
            "/n: names use letters, digits, '_', '-' and '.' only, got \"my soil\"");
  EXPECT_EQ(Message(ReadName(Json(std::string(33, 'a')), "/n", &name)),
            "/n: names have at most 32 characters, got 33");
  ASSERT_TRUE(ReadName(Json(std::string(32, 'a')), "/n", &name).ok());
}

enum class Shape { kLinear, kGimp };
constexpr Table<Shape> kShapes = {
    {"linear", Shape::kLinear}, {"hat", Shape::kLinear}, {"gimp", Shape::kGimp}};
absl::string_view ShapeName(Shape s) { return s == Shape::kGimp ? "gimp" : "linear"; }

TEST(FieldTableReaders, EnumerationsByTable) {
  Shape shape = Shape::kGimp;
  ASSERT_TRUE(ReadEnum(Json("hat"), "/shape", "shape", kShapes, &shape).ok());  // an alias
  EXPECT_EQ(shape, Shape::kLinear);
  EXPECT_EQ(Message(ReadEnum(Json("cubic"), "/shape", "shape function", kShapes, &shape)),
            "/shape: unknown shape function \"cubic\" (linear, hat, gimp)");
  EXPECT_EQ(Message(ReadEnum(Json(3), "/shape", "shape", kShapes, &shape)),
            "/shape: must be a string (linear, hat, gimp), got number 3");
  EXPECT_EQ(Choices(kShapes), "linear, hat, gimp");
}

TEST(FieldTableReaders, Vec2) {
  Eigen::Vector2d v(1, 2);
  EXPECT_EQ(Message(ReadVec2(Json::array({1, 2, 3}), "/g", kAny, &v)),
            "/g: must be an array of 2 numbers [x, y], got array [1,2,3]");
  EXPECT_EQ(Message(ReadVec2(Json::array({0, 1e13}), "/g", kAny, &v)),
            "/g/1: must be at most 1e+12 in magnitude, got 1e+13");
  EXPECT_EQ(v, Eigen::Vector2d(1, 2));  // untouched although /g/0 was read
  ASSERT_TRUE(ReadVec2(Json::array({0, -9.81}), "/g", kAny, &v).ok());
  EXPECT_EQ(v, Eigen::Vector2d(0, -9.81));
}

TEST(FieldTableReaders, TimeRows) {
  std::vector<std::array<double, 3>> rows;
  ASSERT_TRUE(
      ReadTimeRows(Json::parse("[[0, 1], [0.5, -2]]"), "/h", 2, "[t, f] (s, -)", true, &rows).ok());
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[1], (std::array<double, 3>{0.5, -2, 0}));  // unused entries 0
  rows.clear();
  EXPECT_EQ(Message(ReadTimeRows(Json::array(), "/h", 2, "[t, f] (s, -)", true, &rows)),
            "/h: must be a non-empty array of [t, f] (s, -), got array []");
  EXPECT_TRUE(ReadTimeRows(Json::array(), "/h", 2, "[t, f] (s, -)", false, &rows).ok());
  EXPECT_EQ(Message(ReadTimeRows(Json::parse("[[0, 1], [0]]"), "/h", 2, "[t, f]", false, &rows)),
            "/h/1: must be an array of 2 numbers [t, f], got array [0]");
  rows.clear();
  EXPECT_EQ(Message(ReadTimeRows(Json::parse("[[1, 1], [1, 2]]"), "/h", 2, "[t, f]", false, &rows)),
            "/h/1/0: times must increase strictly, got 1 s after 1 s");
  rows.clear();
  EXPECT_EQ(Message(ReadTimeRows(Json::parse("[[-1, 1]]"), "/h", 2, "[t, f]", false, &rows)),
            "/h/0/0: must be >= 0, got -1");
}

TEST(FieldTableReaders, GettersLeaveAbsentOptionalKeysAlone) {
  const Json j = Json::parse(R"({"x": 2, "v": [1, 1]})");
  absl::StatusOr<Object> o = Object::Open(j, "/s", {"x", "y", "v", "w", "n", "t", "e"});
  ASSERT_TRUE(o.ok()) << o.status();
  double y = 3.0;
  ASSERT_TRUE(GetNumber(*o, "y", Need::kOptional, kAny, &y).ok());
  EXPECT_EQ(y, 3.0);
  EXPECT_EQ(Message(GetNumber(*o, "y", Need::kRequired, kAny, &y)),
            "/s/y: required key is missing");
  ASSERT_TRUE(GetNumber(*o, "x", Need::kRequired, kAny, &y).ok());
  EXPECT_EQ(y, 2.0);
  Eigen::Vector2d w(5, 5);
  ASSERT_TRUE(GetVec2(*o, "w", Need::kOptional, kAny, &w).ok());
  EXPECT_EQ(w, Eigen::Vector2d(5, 5));
  std::int64_t n = 4;
  ASSERT_TRUE(GetInteger(*o, "n", 0, 10, &n).ok());
  EXPECT_EQ(n, 4);
  std::string t = "kept";
  ASSERT_TRUE(GetString(*o, "t", Need::kOptional, true, &t).ok());
  EXPECT_EQ(t, "kept");
  Shape e = Shape::kGimp;
  EXPECT_EQ(Message(GetEnum(*o, "e", Need::kRequired, "shape", kShapes, &e)),
            "/s/e: required key is missing");
  EXPECT_EQ(Message(Forbid(*o, "v", "only for circles")), "/s/v: only for circles");
  EXPECT_TRUE(Forbid(*o, "w", "only for circles").ok());
}

struct Item {
  std::string name;
  double size = 1.0;
};

TEST(FieldTableReaders, ListsOfNamedObjects) {
  const Json j = Json::parse(R"({"items": [{"name": "a"}, {"name": "b"}, {"name": "a"}],
                                 "empty": [], "scalar": 3})");
  absl::StatusOr<Object> o = Object::Open(j, "", {"items", "empty", "scalar", "none"});
  ASSERT_TRUE(o.ok()) << o.status();
  std::vector<Item> items;
  std::vector<std::string> pointers;
  const auto parse = [&](const Json& e, const std::string& at, size_t, Item* item) {
    pointers.push_back(at);
    return GetName(*Object::Open(e, at, {"name"}), &item->name);
  };
  EXPECT_EQ(Message(GetList(*o, "items", Need::kOptional, "item", &items, parse)),
            "/items/2/name: duplicate item name \"a\" (also /items/0)");
  EXPECT_EQ(pointers, (std::vector<std::string>{"/items/0", "/items/1", "/items/2"}));
  EXPECT_EQ(NamesOf(items), (std::vector<std::string>{"a", "b", "a"}));
  EXPECT_EQ(Message(GetList(*o, "empty", Need::kRequired, "item", &items, parse)),
            "/empty: must not be empty");
  EXPECT_EQ(Message(GetList(*o, "scalar", Need::kOptional, "item", &items, parse)),
            "/scalar: must be an array, got number 3");
  EXPECT_EQ(Message(GetList(*o, "none", Need::kRequired, "item", &items, parse)),
            "/none: required key is missing");
  // An absent optional list is an empty one.
  items = {{"kept", 2.0}};
  ASSERT_TRUE(GetList(*o, "none", Need::kOptional, "item", &items, parse).ok());
  EXPECT_TRUE(items.empty());
}

TEST(FieldTableReaders, FilesResolveAgainstTheBaseDirectory) {
  const fs::path dir = fs::temp_directory_path() / absl::StrCat("field_table_test_", getpid());
  fs::create_directories(dir / "sub");
  std::ofstream(dir / "sub" / "curve.csv") << "t,f\n";
  const Json j = Json::parse(R"({"here": "sub/../sub/curve.csv", "gone": "missing.csv"})");
  absl::StatusOr<Object> o = Object::Open(j, "/out", {"here", "gone", "absent"});
  ASSERT_TRUE(o.ok()) << o.status();
  std::string path;
  ASSERT_TRUE(GetFile(*o, "here", dir.string(), &path).ok());
  EXPECT_EQ(path, (fs::absolute(dir) / "sub" / "curve.csv").lexically_normal().string());
  EXPECT_EQ(Message(GetFile(*o, "gone", dir.string(), &path)),
            absl::StrCat("/out/gone: no such file \"",
                         (fs::absolute(dir) / "missing.csv").lexically_normal().string(), "\""));
  EXPECT_EQ(Message(GetFile(*o, "absent", dir.string(), &path)),
            "/out/absent: required key is missing");
  fs::remove_all(dir);
}

// A section of a toy model, one field of each kind.
struct Probe {
  std::string name;
  double size = 1.0;
  Eigen::Vector2d at = Eigen::Vector2d::Zero();
  std::int64_t count = 2;
  std::string note;
  bool fixed = false;
  Shape shape = Shape::kLinear;
  double gimp_width = 0.5;  // only for the GIMP shape
  double until = kInf;      // never unless given
};

bool IsGimp(const Probe& p) { return p.shape == Shape::kGimp; }

Fields<Probe> ProbeFields() {
  return {
      NameField<Probe>(),
      NumberField("size", &Probe::size, Need::kRequired, kPositive),
      Vec2Field("at", &Probe::at, Need::kOptional, kAny),
      IntegerField("count", &Probe::count, 1, 10),
      TextField("note", &Probe::note, Need::kOptional, /*non_empty=*/false),
      FlagField("fixed", &Probe::fixed),
      EnumField("shape", &Probe::shape, Need::kOptional, "shape", kShapes, &ShapeName),
      Only(&IsGimp, "only for shape \"gimp\"",
           NumberField("gimp_width", &Probe::gimp_width, Need::kOptional, kPositive)),
      OptionalFiniteField("until", &Probe::until, kNonNegative),
  };
}

absl::StatusOr<Probe> ReadProbe(const std::string& text) {
  Probe p;
  RETURN_IF_ERROR(ReadFields(Json::parse(text), "/probe", ProbeFields(), &p).status());
  return p;
}

TEST(FieldTableFields, ReadInTableOrderAndWrittenCanonically) {
  absl::StatusOr<Probe> p = ReadProbe(
      R"({"until": 3, "shape": "hat", "size": 0.25, "name": "p1", "at": [1, 2], "fixed": false})");
  ASSERT_TRUE(p.ok()) << p.status();
  EXPECT_EQ(p->size, 0.25);
  EXPECT_EQ(p->count, 2);  // default kept
  // Keys in the table's order; the alias written by its value's name; a
  // false flag and a field that does not apply left out.
  EXPECT_EQ(WriteFields(ProbeFields(), *p).dump(),
            R"({"name":"p1","size":0.25,"at":[1.0,2.0],"count":2,"note":"","shape":"linear",)"
            R"("until":3.0})");
  // An infinite `until` is not written; a flag that is set is.
  Probe q = *p;
  q.until = kInf;
  q.fixed = true;
  q.shape = Shape::kGimp;
  EXPECT_EQ(WriteFields(ProbeFields(), q).dump(),
            R"({"name":"p1","size":0.25,"at":[1.0,2.0],"count":2,"note":"","fixed":true,)"
            R"("shape":"gimp","gimp_width":0.5})");
  // What is written reads back the same.
  absl::StatusOr<Probe> again = ReadProbe(WriteFields(ProbeFields(), q).dump());
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_EQ(WriteFields(ProbeFields(), *again).dump(), WriteFields(ProbeFields(), q).dump());
}

TEST(FieldTableFields, TheFirstBadFieldInTableOrderIsReported) {
  // Both "name" and "size" are bad: "name" comes first in the table.
  EXPECT_EQ(Message(ReadProbe(R"({"size": -1, "name": "a b"})").status()),
            "/probe/name: names use letters, digits, '_', '-' and '.' only, got \"a b\"");
  EXPECT_EQ(Message(ReadProbe(R"({"name": "a", "size": 0})").status()),
            "/probe/size: must be > 0, got 0");
  // Unknown keys are found before any field is read.
  EXPECT_EQ(Message(ReadProbe(R"({"name": "a b", "szie": 1})").status()),
            "/probe/szie: unknown key (did you mean \"size\"? keys here: name, size, at, count, "
            "note, fixed, shape, gimp_width, until)");
  EXPECT_EQ(Message(ReadProbe(R"({"name": "a", "size": 1, "fixed": 1})").status()),
            "/probe/fixed: must be true or false, got number 1");
  EXPECT_EQ(Message(ReadProbe(R"({"name": "a", "size": 1, "count": 11})").status()),
            "/probe/count: must be an integer in 1..10, got 11");
}

TEST(FieldTableFields, OnlyRefusesAKeyThatDoesNotApply) {
  EXPECT_EQ(Message(ReadProbe(R"({"name": "a", "size": 1, "gimp_width": 0.1})").status()),
            "/probe/gimp_width: only for shape \"gimp\"");
  absl::StatusOr<Probe> p =
      ReadProbe(R"({"name": "a", "size": 1, "shape": "gimp", "gimp_width": 0.1})");
  ASSERT_TRUE(p.ok()) << p.status();
  EXPECT_EQ(p->gimp_width, 0.1);
}

TEST(FieldTableDocument, SyntaxErrorsNameLineAndColumn) {
  // The parser's own message follows the position (its wording is nlohmann's).
  EXPECT_TRUE(
      absl::StartsWith(Message(ParseJson("{\n  \"grid\": tru\n}").status()),
                       "line 2, column 13: syntax error while parsing value - invalid literal"));
  EXPECT_EQ(Message(ParseJson("{\n\n  \"x\": 1e400}").status()),
            "line 3, column 8: number overflow parsing '1e400'");
  EXPECT_EQ(Message(ParseJson("").status()).substr(0, 31), "line 1, column 1: syntax error ");
}

// 64 levels are read; the 65th bracket is refused before parsing, however
// deep the rest goes (100,000 nested arrays in a typed field once overflowed
// the stack); brackets inside strings do not count.
TEST(FieldTableDocument, NestingIsBounded) {
  const std::string ok = std::string(kMaxJsonDepth, '[') + std::string(kMaxJsonDepth, ']');
  EXPECT_TRUE(ParseJson(ok).ok()) << ParseJson(ok).status();
  for (int depth : {kMaxJsonDepth + 1, 100'000}) {
    const std::string deep =
        absl::StrCat("{\"grid\": {\"cell_size\": ", std::string(depth - 2, '['), "1",
                     std::string(depth - 2, ']'), "}}");
    EXPECT_EQ(Message(ParseJson(deep).status()),
              "line 1, column 86: nested deeper than 64 arrays and objects");
  }
  const std::string mixed = absl::StrCat("{\"", std::string(100, '['), "\\\"\": 1}");
  EXPECT_TRUE(ParseJson(mixed).ok()) << ParseJson(mixed).status();
}

TEST(FieldTableDocument, DuplicateKeysAreRefused) {
  EXPECT_EQ(Message(ParseJson(R"({"a": [{"b": 1}, {"c": 1, "c": 2}]})").status()),
            "/a/1/c: duplicate key (an object holds each key once)");
  absl::StatusOr<Json> ok = ParseJson(R"({"a": [{"b": 1}, {"b": 2}]})");
  ASSERT_TRUE(ok.ok()) << ok.status();
  EXPECT_EQ((*ok)["a"][1]["b"], 2);
}

TEST(FieldTableDocument, OverridesParsePointersAndDottedPaths) {
  absl::StatusOr<Override> dotted = ParseOverride("a/b.0.c=x=y", "EXAMPLE");
  ASSERT_TRUE(dotted.ok()) << dotted.status();
  EXPECT_EQ(dotted->pointer, "/a~1b/0/c");  // each dotted token escaped
  EXPECT_EQ(dotted->value, "x=y");
  absl::StatusOr<Override> pointer = ParseOverride("/a~1b/0=[1, 2]", "EXAMPLE");
  ASSERT_TRUE(pointer.ok()) << pointer.status();
  EXPECT_EQ(pointer->pointer, "/a~1b/0");
  EXPECT_EQ(Message(ParseOverride("a.b", "--set=/a/b=1").status()),
            "--set needs PATH=VALUE (e.g. --set=/a/b=1), got 'a.b'");
  EXPECT_EQ(Message(ParseOverride("=1", "--set=/a/b=1").status()),
            "--set needs PATH=VALUE (e.g. --set=/a/b=1), got '=1'");
}

TEST(FieldTableDocument, OverridesChangeExistingParents) {
  Json doc = Json::parse(R"({"a": {"b": 1}, "list": [1, 2], "n": 3})");
  ASSERT_TRUE(ApplyOverride("/a/b", "[1, 2]", doc).ok());
  ASSERT_TRUE(ApplyOverride("/a/new", "sweep-3", doc).ok());  // a bare word: a string
  ASSERT_TRUE(ApplyOverride("/list/1", "\"x\"", doc).ok());
  EXPECT_EQ(doc.dump(), R"({"a":{"b":[1,2],"new":"sweep-3"},"list":[1,"x"],"n":3})");
  EXPECT_EQ(Message(ApplyOverride("/list/2", "1", doc)), "--set /list/2: /list has 2 elements");
  EXPECT_EQ(Message(ApplyOverride("/x/y", "1", doc)), "--set /x/y: /x is not in the case");
  EXPECT_EQ(Message(ApplyOverride("/n/y", "1", doc)), "--set /n/y: /n is not an object or array");
  EXPECT_EQ(Message(ApplyOverride("", "1", doc)), "--set : names the whole case");
  EXPECT_EQ(Message(ApplyOverride("a", "1", doc)).substr(0, 28), "--set a: not a JSON pointer ");
  ASSERT_TRUE(ApplyOverride("/top", "1", doc).ok());  // the root's parent is "the case"
  EXPECT_EQ(doc["top"], 1);
}

TEST(FieldTableDocument, CanonicalLayoutKeepsScalarArraysOnOneLine) {
  OrderedJson j = OrderedJson::parse(
      R"({"b": [1, 2], "a": {"rows": [[0, 1], [2, 3]], "none": [], "o": {}}, "s": "x"})");
  EXPECT_EQ(FormatJson(j),
            "{\n"
            "  \"b\": [1, 2],\n"
            "  \"a\": {\n"
            "    \"rows\": [\n"
            "      [0, 1],\n"
            "      [2, 3]\n"
            "    ],\n"
            "    \"none\": [],\n"
            "    \"o\": {}\n"
            "  },\n"
            "  \"s\": \"x\"\n"
            "}");
}

}  // namespace
}  // namespace rvehub::fields
