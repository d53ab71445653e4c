#include "toolkit/json_pointer.h"

#include "absl/strings/str_format.h"

namespace rvehub::fields {

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

std::string Num(double x) { return absl::StrFormat("%.10g", x); }

std::string Quote(absl::string_view s) { return absl::StrCat("\"", s, "\""); }

std::string Got(const Json& v) {
  if (v.is_null()) return "null";
  std::string text = v.dump(-1, ' ', false, Json::error_handler_t::replace);
  if (text.size() > 60) text = text.substr(0, 57) + "...";
  return absl::StrCat(v.type_name(), " ", text);
}

}  // namespace rvehub::fields
