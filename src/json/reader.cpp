#include "json/reader.h"

#include "common/did_you_mean.h"
#include "common/error.h"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <set>
#include <sstream>

namespace hs {

using nlohmann::json;

// ---------------------------------------------------------------- documents

namespace {

/// Where the parser is in the document, kept by the parser callback so that problems found
/// while parsing (too deep, a duplicate key, a number out of range) name their JSON pointer.
class ParsePosition {
 public:
  /// The pointer of the value being parsed now ("/time/dt", "/walls/0").
  std::string pointer() const {
    std::string p;
    for (const Frame& f : frames_) {
      if (f.object) {
        if (f.has_key) p += "/" + json_pointer_token(f.key);
      } else {
        p += "/" + std::to_string(f.index);
      }
    }
    return p;
  }
  /// The parser callback: tracks the position, refuses duplicate keys and deep nesting.
  bool on_event(json::parse_event_t event, const json& parsed) {
    using E = json::parse_event_t;
    switch (event) {
      case E::object_start:
      case E::array_start:
        if (frames_.size() >= kJsonMaxDepth)
          throw InputError(json_pointer_display(short_pointer()),
                           "JSON nesting deeper than " + std::to_string(kJsonMaxDepth) +
                               " levels of objects and arrays; a scene needs a handful: check the file for "
                               "runaway brackets");
        frames_.emplace_back();
        frames_.back().object = event == E::object_start;
        break;
      case E::key: {
        Frame& f = frames_.back();
        f.key = parsed.get<std::string>();
        f.has_key = true;
        if (!f.keys.insert(f.key).second)
          throw InputError(json_pointer_display(pointer()),
                           "duplicate key \"" + f.key + "\": it is given twice in the same object and only one value "
                           "can be used; remove one of them");
        break;
      }
      case E::object_end:
      case E::array_end:
        frames_.pop_back();
        [[fallthrough]];
      case E::value:
        if (!frames_.empty()) {
          Frame& f = frames_.back();
          if (f.object)
            f.has_key = false;
          else
            ++f.index;
        }
        break;
    }
    return true;
  }

 private:
  struct Frame {
    bool object = false;
    std::size_t index = 0;  ///< arrays: elements completed so far
    std::string key;        ///< objects: the current key
    bool has_key = false;
    std::set<std::string> keys{};
  };
  /// The pointer cut to its first levels (a runaway nesting would make it enormous).
  std::string short_pointer() const {
    std::string p = pointer();
    if (p.size() > 80) p = p.substr(0, 80) + "...";
    return p;
  }
  std::vector<Frame> frames_;
};

}  // namespace

json parse_json_text(const std::string& text, const std::string& source) {
  ParsePosition pos;
  try {
    return json::parse(text, [&pos](int, json::parse_event_t event, json& parsed) { return pos.on_event(event, parsed); });
  } catch (const json::out_of_range& e) {
    // nlohmann: "[json.exception.out_of_range.406] number overflow parsing '1e400'"
    std::string what = e.what();
    const std::size_t b = what.find("] ");
    if (b != std::string::npos) what = what.substr(b + 2);
    throw InputError(json_pointer_display(pos.pointer()),
                     what + ": the number is beyond the range of a double (about 1.8e308); give a finite value");
  } catch (const json::parse_error& e) {
    // Byte offset -> line and column (1-based).
    std::size_t line = 1, col = 1;
    const std::size_t end = std::min<std::size_t>(e.byte == 0 ? 0 : e.byte - 1, text.size());
    for (std::size_t i = 0; i < end; ++i) {
      if (text[i] == '\n') {
        ++line;
        col = 1;
      } else {
        ++col;
      }
    }
    std::string what = e.what();
    // nlohmann: "[json.exception.parse_error.101] parse error at line 3, column 5: syntax error ..."
    const std::size_t colon = what.find(": ", what.find("parse error"));
    if (colon != std::string::npos) what = what.substr(colon + 2);
    throw InputError(source, "invalid JSON at line " + std::to_string(line) + ", column " + std::to_string(col) +
                                 ": " + what + "; fix the syntax there (a missing comma or quote, or a trailing "
                                               "comma, is the usual cause)");
  }
}

json read_json_file(const std::string& path, const std::string& what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open the " + what + ": " + std::strerror(errno) +
                                      "; check the path (relative paths start from the current directory)");
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_json_text(ss.str(), path);
}

// ---------------------------------------------------------------- message pieces

std::string json_show(const json& v) {
  std::string s = v.dump();
  if (s.size() > 60) s = s.substr(0, 57) + "...";
  return s;
}

std::string json_got(const json& v) {
  return v.is_null() ? std::string("null") : std::string(v.type_name()) + " " + json_show(v);
}

std::string json_fmt(double x) {
  std::ostringstream s;
  s.precision(6);
  s << x;
  return s.str();
}

std::string json_pointer_token(const std::string& key) {
  std::string out;
  for (char ch : key) {
    if (ch == '~')
      out += "~0";
    else if (ch == '/')
      out += "~1";
    else
      out += ch;
  }
  return out;
}

std::string json_pointer_display(const std::string& pointer) { return pointer.empty() ? "/" : pointer; }

std::string unknown_key_text(const std::string& key, const std::vector<std::string>& allowed) {
  std::string list;
  for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
  return "unknown key \"" + key + "\"" + did_you_mean(key, allowed) + "; allowed here: " + list;
}

// ---------------------------------------------------------------- values

bool JsonRange::contains(double x) const {
  if (lo_open ? !(x > lo) : !(x >= lo)) return false;
  if (hi_open ? !(x < hi) : !(x <= hi)) return false;
  return true;
}

std::string JsonRange::describe(const std::string& unit) const {
  const std::string u = unit.empty() ? "" : " " + unit;
  std::string s;
  if (std::isfinite(lo)) s += (lo_open ? "> " : ">= ") + json_fmt(lo) + u;
  if (std::isfinite(hi)) s += (s.empty() ? "" : " and ") + std::string(hi_open ? "< " : "<= ") + json_fmt(hi) + u;
  return s.empty() ? "any finite number" : s;
}

namespace json_detail {

void bad_vector(const json& v, const std::string& pointer, int n, const std::string& unit, const std::string& hint) {
  throw InputError(pointer, "expected an array of " + std::to_string(n) + " numbers" +
                                (unit.empty() ? std::string() : " in " + unit) + ", got " + json_got(v) + "; " + hint);
}

void bad_element(const json& e, const std::string& pointer, const std::string& hint) {
  throw InputError(pointer, "expected a finite number, got " + json_got(e) + "; " + hint);
}

void not_whole(const json& v, const std::string& pointer, const std::string& hint) {
  throw InputError(pointer, "expected a whole number, got " + json_show(v) + "; " + hint);
}

}  // namespace json_detail

// ---------------------------------------------------------------- objects

JsonObject::JsonObject(const json& j, std::string pointer, const std::vector<std::string>& allowed,
                       const std::string& help, JsonNull nulls)
    : j_(j), ptr_(std::move(pointer)), nulls_(nulls) {
  if (!j.is_object())
    throw InputError(json_pointer_display(ptr_),
                     "expected an object {...}, got " + json_got(j) + (help.empty() ? "" : "; " + help));
  for (const auto& [key, value] : j.items())
    if (std::find(allowed.begin(), allowed.end(), key) == allowed.end())
      throw InputError(at(key), unknown_key_text(key, allowed));
}

bool JsonObject::has(const std::string& key) const {
  const auto it = j_.find(key);
  if (it == j_.end()) return false;
  return !(nulls_ == JsonNull::IsAbsent && it->is_null());
}

JsonObject JsonObject::object(const std::string& key, const std::vector<std::string>& allowed,
                              const std::string& help) const {
  return JsonObject(raw(key), at(key), allowed, help, nulls_);
}

const json& JsonObject::array(const std::string& key, const std::string& what) const {
  const json& v = raw(key);
  if (!v.is_array()) throw InputError(at(key), "expected an array of " + what + ", got " + json_got(v));
  return v;
}

void JsonObject::missing(const std::string& key, const std::string& what) const {
  throw InputError(at(key), "missing required field \"" + key + "\" (" + what + "); add it to the \"" +
                                (ptr_.empty() ? std::string("top level") : ptr_.substr(1)) + "\" object");
}

const json& JsonObject::number_value(const std::string& key, const std::string& unit, const std::string& hint) const {
  const json& v = j_.at(key);
  if (!v.is_number())
    throw InputError(at(key), "expected a number" + (unit.empty() ? std::string() : " in " + unit) + ", got " +
                                  json_got(v) + "; " + hint);
  return v;
}

void JsonObject::out_of_range(const std::string& key, const json& v, const JsonRange& range, const std::string& unit,
                              const std::string& hint) const {
  throw InputError(at(key), "value " + json_show(v) + (unit.empty() ? "" : " " + unit) +
                                " is out of range: must be " + range.describe(unit) + "; " + hint);
}

double JsonObject::number(const std::string& key, double def, JsonRange range, const std::string& unit,
                          const std::string& hint, bool required, const std::string& what) const {
  if (!has(key)) {
    if (required) missing(key, what.empty() ? hint : what);
    return def;
  }
  const json& v = number_value(key, unit, hint);
  const double x = v.get<double>();
  if (!std::isfinite(x) || !range.contains(x)) out_of_range(key, v, range, unit, hint);
  return x;
}

bool JsonObject::boolean(const std::string& key, bool def) const {
  if (!has(key)) return def;
  const json& v = j_.at(key);
  if (!v.is_boolean()) throw InputError(at(key), "expected true or false, got " + json_got(v));
  return v.get<bool>();
}

std::string JsonObject::string(const std::string& key, const std::string& def, bool required,
                               const std::string& what) const {
  if (!has(key)) {
    if (required) missing(key, what);
    return def;
  }
  const json& v = j_.at(key);
  if (!v.is_string()) throw InputError(at(key), "expected a string, got " + json_got(v) + "; " + what);
  return v.get<std::string>();
}

std::string JsonObject::choice(const std::string& key, const std::string& def, const std::vector<std::string>& allowed,
                               const std::string& hint) const {
  std::string list;
  for (const auto& a : allowed) list += (list.empty() ? "\"" : ", \"") + a + "\"";
  const std::string tail = hint.empty() ? "" : "; " + hint;
  const std::string s = string(key, def, false, "use one of " + list + tail);
  if (std::find(allowed.begin(), allowed.end(), s) == allowed.end())
    throw InputError(at(key),
                     "\"" + s + "\" is not allowed" + did_you_mean(s, allowed) + "; use one of " + list + tail);
  return s;
}

std::string json_first_difference(const nlohmann::json& a, const nlohmann::json& b, const std::string& at) {
  if (a.type() != b.type()) return at.empty() ? "/" : at;
  if (a.is_object()) {
    for (auto it = a.begin(); it != a.end(); ++it) {
      if (!b.contains(it.key())) return at + "/" + json_pointer_token(it.key());
      const std::string d = json_first_difference(it.value(), b[it.key()], at + "/" + json_pointer_token(it.key()));
      if (!d.empty()) return d;
    }
    for (auto it = b.begin(); it != b.end(); ++it)
      if (!a.contains(it.key())) return at + "/" + json_pointer_token(it.key());
    return "";
  }
  if (a.is_array()) {
    for (std::size_t k = 0; k < std::min(a.size(), b.size()); ++k) {
      const std::string d = json_first_difference(a[k], b[k], at + "/" + std::to_string(k));
      if (!d.empty()) return d;
    }
    return a.size() == b.size() ? "" : at + "/" + std::to_string(std::min(a.size(), b.size()));
  }
  return a == b ? "" : (at.empty() ? "/" : at);
}

}  // namespace hs
