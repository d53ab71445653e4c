#include "toolkit/json_document.h"

#include <algorithm>
#include <cctype>
#include <cstddef>
#include <functional>
#include <set>
#include <utility>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"

namespace rvehub::fields {
namespace {

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

// InvalidArgument at the first bracket deeper than kMaxJsonDepth, found
// before parsing: a document nested 100,000 deep would otherwise be copied
// and walked recursively (stack overflow) after parsing.
absl::Status CheckNesting(absl::string_view text) {
  int depth = 0;
  bool in_string = false, escaped = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
      } else if (c == '"') {
        in_string = false;
      }
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > kMaxJsonDepth) {
        return absl::InvalidArgumentError(absl::StrCat(Position(text, i), ": nested deeper than ",
                                                       kMaxJsonDepth, " arrays and objects"));
      }
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return absl::OkStatus();
}

std::string Dump(const OrderedJson& j) {
  return j.dump(-1, ' ', false, OrderedJson::error_handler_t::replace);
}

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

absl::StatusOr<Json> ParseJson(absl::string_view text) {
  if (absl::Status s = CheckNesting(text); !s.ok()) return s;
  Json doc;
  DuplicateKeys duplicates;
  try {
    doc = Json::parse(text.begin(), text.end(), std::ref(duplicates));
  } catch (const Json::exception& e) {
    return SyntaxError(e, text);
  }
  if (!duplicates.first().empty()) {
    return Bad(duplicates.first(), "duplicate key (an object holds each key once)");
  }
  return doc;
}

absl::StatusOr<Override> ParseOverride(absl::string_view text, absl::string_view example) {
  const std::size_t eq = text.find('=');
  if (eq == absl::string_view::npos || eq == 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("--set needs PATH=VALUE (e.g. ", example, "), got '", text, "'"));
  }
  Override o;
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

absl::Status ApplyOverride(absl::string_view pointer_text, absl::string_view value_text,
                           Json& doc) {
  const std::string what = absl::StrCat("--set ", pointer_text);
  Json::json_pointer pointer;
  try {
    pointer = Json::json_pointer(std::string(pointer_text));
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
    // Only existing elements: an override changes a document, it does not grow lists.
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
    value = Json::parse(std::string(value_text));
  } catch (const Json::exception&) {
    value = std::string(value_text);  // a bare word: a string
  }
  doc[pointer] = std::move(value);
  return absl::OkStatus();
}

std::string FormatJson(const OrderedJson& j) {
  std::string out;
  Write(j, 0, &out);
  return out;
}

}  // namespace rvehub::fields
