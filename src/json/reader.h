// The one JSON reader of user input: scenes (src/scene), ridge scenes (src/rigid), ISO 19906
// input files (src/analysis) and the `hybridsim ridge` command all read through it, so every
// input file reports problems the same way.
//
// Every problem is an hs::InputError whose path is the JSON pointer of the offending value
// ("/ice/thickness", "/walls/0/normal/2") and whose message says what was given, what is
// allowed (with the unit) and how to fix it:
//
//   /ice/thickness: value -0.5 m is out of range: must be > 0 m; e.g. 0.6
//   /ice/thicknes: unknown key "thicknes" (did you mean "thickness"?); allowed here: type, ...
//   /water/enabled: expected true or false, got string "yes"
//
// Use: construct a JsonObject on each object of the document with the keys it may hold
// (unknown keys are refused at construction), then read each field with a typed getter that
// returns the value or the given default when the key is absent:
//
//   const JsonObject o(j.at("time"), "/time", {"duration", "dt"});
//   t.duration = o.number("duration", 0, JsonRange::positive(), "s", "e.g. 10", true, "simulated time, s");
//
// Units are labels: values are numbers in the SI unit the caller names, and the unit appears
// in every message about that value ("expected a number in m", "must be > 0 m").
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

namespace hs {

// ---------------------------------------------------------------- documents

/// Deepest nesting of objects and arrays parse_json_text accepts (a scene needs about 5).
inline constexpr std::size_t kJsonMaxDepth = 100;

/// Parses JSON text; syntax errors become InputError(source, "invalid JSON at line L, column C:
/// ...; fix the syntax there ..."). `source` names the text (file name) in messages. Found while
/// parsing, before the document is built, and reported at their JSON pointer: nesting deeper
/// than kJsonMaxDepth, a key given twice in one object, a number beyond the range of a double
/// (1e400).
nlohmann::json parse_json_text(const std::string& text, const std::string& source);

/// Reads a file and parses it; a missing or unreadable file is InputError(path, "cannot open the
/// <what>: <reason>; check the path ...").
nlohmann::json read_json_file(const std::string& path, const std::string& what = "scene file");

// ---------------------------------------------------------------- message pieces

/// The value as compact JSON text, cut to 60 characters ("[1,2,3]", "\"yes\"").
std::string json_show(const nlohmann::json& v);
/// Its type and value: `string "yes"`, `number -1`, `array [1,2]`, `null`.
std::string json_got(const nlohmann::json& v);
/// A number with 6 significant digits ("0.6", "1e+30").
std::string json_fmt(double x);
/// RFC 6901 escaping of one JSON pointer token ("a/b" -> "a~1b").
std::string json_pointer_token(const std::string& key);
/// The root is shown as "/" in messages; any other pointer as is.
std::string json_pointer_display(const std::string& pointer);
/// `unknown key "k" (did you mean "x"?); allowed here: a, b, c` for a key not in `allowed`.
std::string unknown_key_text(const std::string& key, const std::vector<std::string>& allowed);
/// The first JSON pointer at which `a` and `b` differ (object keys in a's order, then keys only b
/// has; array elements by index): "" when equal, "/" when the roots differ in type or value.
std::string json_first_difference(const nlohmann::json& a, const nlohmann::json& b, const std::string& at = "");

// ---------------------------------------------------------------- values

/// An allowed interval of a number: closed or open at each end, unbounded by default.
struct JsonRange {
  double lo = -INFINITY, hi = INFINITY;
  bool lo_open = false, hi_open = false;
  static JsonRange positive() { return {0.0, INFINITY, true, false}; }      ///< > 0
  static JsonRange non_negative() { return {0.0, INFINITY, false, false}; } ///< >= 0
  static JsonRange any() { return {}; }                                     ///< any finite number
  bool contains(double x) const;
  /// "> 0 m", ">= 0 and < 1", "any finite number".
  std::string describe(const std::string& unit) const;
};

/// Reads `v` (found at `pointer`) as N finite numbers: InputError at `pointer` if it is not an
/// array of N, at `pointer/k` for a bad element. `unit` and `hint` go into the messages.
template <int N>
Eigen::Matrix<double, N, 1> json_vector(const nlohmann::json& v, const std::string& pointer,
                                        const std::string& unit, const std::string& hint);

/// How a reader treats `"key": null`.
enum class JsonNull {
  IsWrongType,  ///< null is a value of the wrong type (scenes, ISO inputs)
  IsAbsent,     ///< null means "not given": the default is used (ridge definitions write null)
};

// ---------------------------------------------------------------- objects

/// One JSON object being read. The constructor refuses a non-object and any key not in
/// `allowed` (with a did-you-mean suggestion and the allowed list); the getters check types
/// and ranges. The object is held by reference: it must outlive the reader.
class JsonObject {
 public:
  /// `pointer`: where the object is ("" for the document root, "/ice", "/walls/0").
  /// `help`: appended to the "expected an object" error, e.g. "see docs/scene.md ...".
  JsonObject(const nlohmann::json& j, std::string pointer, const std::vector<std::string>& allowed,
             const std::string& help = "", JsonNull nulls = JsonNull::IsWrongType);

  const std::string& pointer() const { return ptr_; }
  /// The pointer of a key of this object ("/ice" + "thickness" -> "/ice/thickness").
  std::string at(const std::string& key) const { return ptr_ + "/" + json_pointer_token(key); }
  /// Whether the key is given (a null counts as absent with JsonNull::IsAbsent).
  bool has(const std::string& key) const;
  /// The value of a key that is present (unchecked).
  const nlohmann::json& raw(const std::string& key) const { return j_.at(key); }
  /// A reader for the object at `key` (which must be present), with the same null rule.
  JsonObject object(const std::string& key, const std::vector<std::string>& allowed, const std::string& help) const;
  /// The array at `key` (which must be present); InputError "expected an array of <what>".
  const nlohmann::json& array(const std::string& key, const std::string& what) const;

  /// InputError: missing required field "key" (what); add it to the "..." object.
  [[noreturn]] void missing(const std::string& key, const std::string& what) const;

  /// A finite number in `range`; `def` when absent (or InputError if `required`; the message
  /// then uses `what`, else `hint`). `unit` labels the number in messages ("" for none).
  double number(const std::string& key, double def, JsonRange range, const std::string& unit,
                const std::string& hint, bool required = false, const std::string& what = "") const;

  /// A whole number in `range` that fits T (JSON integers are read exactly, so 64-bit seeds
  /// survive; a float is accepted when it is whole, e.g. 20.0).
  template <class T>
  T integer(const std::string& key, T def, JsonRange range, const std::string& unit, const std::string& hint) const;

  bool boolean(const std::string& key, bool def) const;

  /// A string; `def` when absent (InputError if `required`). `what` describes it in messages.
  std::string string(const std::string& key, const std::string& def, bool required = false,
                     const std::string& what = "") const;

  /// One of the `allowed` words (did-you-mean on a near miss); `hint` explains the words.
  std::string choice(const std::string& key, const std::string& def, const std::vector<std::string>& allowed,
                     const std::string& hint = "") const;

  /// N finite numbers, see json_vector.
  template <int N>
  Eigen::Matrix<double, N, 1> vec(const std::string& key, const Eigen::Matrix<double, N, 1>& def,
                                  const std::string& unit, const std::string& hint) const {
    if (!has(key)) return def;
    return json_vector<N>(j_.at(key), at(key), unit, hint);
  }

 private:
  /// The present value at `key` checked to be a number (InputError otherwise).
  const nlohmann::json& number_value(const std::string& key, const std::string& unit, const std::string& hint) const;
  [[noreturn]] void out_of_range(const std::string& key, const nlohmann::json& v, const JsonRange& range,
                                 const std::string& unit, const std::string& hint) const;

  const nlohmann::json& j_;
  std::string ptr_;
  JsonNull nulls_;
};

// ---------------------------------------------------------------- templates

namespace json_detail {
[[noreturn]] void bad_vector(const nlohmann::json& v, const std::string& pointer, int n, const std::string& unit,
                             const std::string& hint);
[[noreturn]] void bad_element(const nlohmann::json& e, const std::string& pointer, const std::string& hint);
[[noreturn]] void not_whole(const nlohmann::json& v, const std::string& pointer, const std::string& hint);
}  // namespace json_detail

template <int N>
Eigen::Matrix<double, N, 1> json_vector(const nlohmann::json& v, const std::string& pointer,
                                        const std::string& unit, const std::string& hint) {
  if (!v.is_array() || v.size() != static_cast<std::size_t>(N)) json_detail::bad_vector(v, pointer, N, unit, hint);
  Eigen::Matrix<double, N, 1> out;
  for (int k = 0; k < N; ++k) {
    const nlohmann::json& e = v[static_cast<std::size_t>(k)];
    if (!e.is_number() || !std::isfinite(e.get<double>()))
      json_detail::bad_element(e, pointer + "/" + std::to_string(k), hint);
    out[k] = e.get<double>();
  }
  return out;
}

template <class T>
T JsonObject::integer(const std::string& key, T def, JsonRange range, const std::string& unit,
                      const std::string& hint) const {
  static_assert(std::is_integral_v<T>);
  if (!has(key)) return def;
  const nlohmann::json& v = number_value(key, unit, hint);
  // The type's own limits join the caller's range.
  if (static_cast<double>(std::numeric_limits<T>::min()) > range.lo) {
    range.lo = static_cast<double>(std::numeric_limits<T>::min());
    range.lo_open = false;
  }
  if (static_cast<double>(std::numeric_limits<T>::max()) < range.hi) {
    range.hi = static_cast<double>(std::numeric_limits<T>::max());
    range.hi_open = false;
  }
  if (v.is_number_unsigned()) {
    const std::uint64_t u = v.get<std::uint64_t>();
    if (u > static_cast<std::uint64_t>(std::numeric_limits<T>::max()) || !range.contains(static_cast<double>(u)))
      out_of_range(key, v, range, unit, hint);
    return static_cast<T>(u);
  }
  if (v.is_number_integer()) {  // negative
    const std::int64_t i = v.get<std::int64_t>();
    if (std::is_unsigned_v<T> || i < static_cast<std::int64_t>(std::numeric_limits<T>::min()) ||
        !range.contains(static_cast<double>(i)))
      out_of_range(key, v, range, unit, hint);
    return static_cast<T>(i);
  }
  const double x = v.get<double>();
  if (!std::isfinite(x) || x != std::floor(x)) json_detail::not_whole(v, at(key), hint);
  // Strictly inside the type's limits, so the conversion is exact.
  if (!range.contains(x) || !(x < static_cast<double>(std::numeric_limits<T>::max())))
    out_of_range(key, v, range, unit, hint);
  return static_cast<T>(x);
}

}  // namespace hs
