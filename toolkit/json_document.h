// A JSON input file as a document: parsed with positions in its errors and
// duplicate keys refused, changed by command-line overrides ("--set
// PATH=VALUE") before it is read, and written back in a canonical layout.
#ifndef RVEHUB_TOOLKIT_JSON_DOCUMENT_H_
#define RVEHUB_TOOLKIT_JSON_DOCUMENT_H_

#include <string>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "toolkit/json_pointer.h"

namespace rvehub::fields {

// Arrays and objects nested deeper than this are refused before parsing (an
// input file needs a handful of levels).
inline constexpr int kMaxJsonDepth = 64;

// Parses `text`. A document nested deeper than kMaxJsonDepth is
// InvalidArgument "line L, column C: nested deeper than 64 arrays and
// objects" at the first bracket too deep. A syntax error is InvalidArgument "line L, column C:
// <parser message>" (1-based, at the last non-blank character the parser
// read; a number out of range, "line L, column C: number overflow parsing
// '1e400'", at the number). A key repeated within one object, which JSON
// parsers otherwise resolve silently to the last value, is InvalidArgument
// "<pointer of the first repeat>: duplicate key (an object holds each key
// once)".
absl::StatusOr<Json> ParseJson(absl::string_view text);

// One value of a document set from outside the file.
struct Override {
  std::string pointer;  // JSON pointer of the value, e.g. "/rve/min_steps"
  std::string value;    // JSON text, e.g. "4", "[1, 2]", "\"gimp\""
};

// "PATH=VALUE": PATH a JSON pointer ("/a/b", "/list/0/c") or the same with
// dots ("a.b", "list.0.c", each token escaped); VALUE is kept as text. A text
// without "=" or with an empty path is InvalidArgument "--set needs
// PATH=VALUE (e.g. <example>), got '<text>'".
absl::StatusOr<Override> ParseOverride(absl::string_view text, absl::string_view example);

// Sets `pointer` in `doc` to `value` parsed as JSON, or to the string
// `value` when it does not parse (--set name=sweep-3). The parent must be in
// the document and an object (a new key is added: the reader then refuses
// it if unknown) or an array with that element (lists do not grow).
// InvalidArgument "--set <pointer>: <why>": "not a JSON pointer (<parser
// message>)", "names the whole case", "<parent> is not in the case",
// "<parent> has <n> elements", "<parent> is not an object or array"
// (<parent> is "the case" for the root).
absl::Status ApplyOverride(absl::string_view pointer, absl::string_view value, Json& doc);

// Two-space indented JSON like dump(2), but arrays of scalars ([x, y],
// [t, vx, vy]) stay on one line, so the output reads like a hand-written
// file. Invalid UTF-8 is replaced. No trailing newline.
std::string FormatJson(const OrderedJson& j);

}  // namespace rvehub::fields

#endif  // RVEHUB_TOOLKIT_JSON_DOCUMENT_H_
