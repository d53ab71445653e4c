// JSON pointers (RFC 6901) and the messages that name them: every error a
// field-table reader returns is InvalidArgument "<pointer>: <what is wrong>",
// e.g. "/solver/cfl: must be in (0, 1], got 1.5".
#ifndef RVEHUB_TOOLKIT_JSON_POINTER_H_
#define RVEHUB_TOOLKIT_JSON_POINTER_H_

#include <cstddef>
#include <nlohmann/json.hpp>
#include <string>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"

namespace rvehub::fields {

using Json = nlohmann::json;
// Keeps keys in insertion order: what the canonical writers produce.
using OrderedJson = nlohmann::ordered_json;

// RFC 6901 escaping of one reference token: "~" -> "~0", "/" -> "~1".
std::string Escape(absl::string_view token);

// The pointer of a member ("/a" + "b/c" -> "/a/b~1c") or an element ("/a/3").
std::string Child(absl::string_view ptr, absl::string_view key);
std::string Child(absl::string_view ptr, size_t index);

// InvalidArgument "<ptr>: <what...>" (the parts concatenated by StrCat);
// the empty pointer, the whole document, reads "(document)".
template <typename... Args>
absl::Status Bad(absl::string_view ptr, const Args&... what) {
  return absl::InvalidArgumentError(
      absl::StrCat(ptr.empty() ? absl::string_view("(document)") : ptr, ": ", what...));
}

// A number in a message: %.10g, enough digits to tell 0.3 from 0.30001,
// fewer than a full round trip.
std::string Num(double x);

// "\"s\"".
std::string Quote(absl::string_view s);

// A value in a "got ..." of a type error: its type name and its JSON text,
// cut to 57 characters and "..." past 60: "string \"abc\"", "array [1,2]",
// "null".
std::string Got(const Json& v);

}  // namespace rvehub::fields

#endif  // RVEHUB_TOOLKIT_JSON_POINTER_H_
