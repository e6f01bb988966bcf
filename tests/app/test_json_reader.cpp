// The shared JSON reader (src/json/reader.h) that scenes, ridge scenes and ISO inputs use:
// every error names the JSON pointer of the bad value, shows the value and its unit, and
// says what is allowed; unknown keys get a did-you-mean suggestion and the allowed list.
#include "common/error.h"
#include "json/reader.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>

using hs::InputError;
using hs::JsonNull;
using hs::JsonObject;
using hs::JsonRange;
using nlohmann::json;

namespace {

/// Runs f, expects an InputError; returns "path | message".
std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.path() + " | " + e.what();
  }
  return "no error";
}

bool contains(const std::string& text, const std::string& needle) { return text.find(needle) != std::string::npos; }

const json doc = json::parse(R"({
  "ice": {"thickness": 0.6, "name": 3, "on": "yes", "origin": [1, "x"], "corner": [1, 2, 3],
          "seed": 18446744073709551615, "count": 20.0, "half": 6.5, "neg": -1, "big": 3000000000,
          "model": "hertzz", "none": null}
})");

JsonObject ice(JsonNull nulls = JsonNull::IsWrongType) {
  return JsonObject(doc.at("ice"), "/ice",
                    {"thickness", "name", "on", "origin", "corner", "seed", "count", "half", "neg", "big", "model",
                     "none"},
                    "", nulls);
}

}  // namespace

TEST(JsonReader, UnknownKeyNamesItsPathSuggestsTheNearestAndListsTheAllowed) {
  const json j = {{"ice", {{"thicknes", 1}}}};
  const std::string e = error_of([&] { JsonObject(j.at("ice"), "/ice", {"thickness", "length", "width"}); });
  EXPECT_TRUE(contains(e, "/ice/thicknes | /ice/thicknes: unknown key \"thicknes\"")) << e;
  EXPECT_TRUE(contains(e, "(did you mean \"thickness\"?)")) << e;
  EXPECT_TRUE(contains(e, "allowed here: thickness, length, width")) << e;
  // Nothing close: no suggestion, still the list.
  const std::string far = error_of([&] { JsonObject(json{{"colour", 1}}, "", {"thickness", "length"}); });
  EXPECT_TRUE(contains(far, "/colour | ")) << far;
  EXPECT_FALSE(contains(far, "did you mean")) << far;
  EXPECT_TRUE(contains(far, "allowed here: thickness, length")) << far;
  // Keys are escaped as JSON pointer tokens (RFC 6901).
  EXPECT_TRUE(contains(error_of([&] { JsonObject(json{{"a/b~", 1}}, "/x", {"ab"}); }), "/x/a~1b~0 | ")) << "escaping";
}

TEST(JsonReader, NotAnObjectNamesThePathAndTheHelp) {
  const std::string root = error_of([] { JsonObject(json::array({1}), "", {"a"}, "see docs/x.md"); });
  EXPECT_EQ(root, "/ | /: expected an object {...}, got array [1]; see docs/x.md");
  const std::string nested = error_of([] { JsonObject(json(3), "/time", {"a"}); });
  EXPECT_EQ(nested, "/time | /time: expected an object {...}, got number 3");
}

TEST(JsonReader, WrongTypes) {
  const JsonObject o = ice();
  EXPECT_EQ(error_of([&] { o.number("on", 0, JsonRange::any(), "m", "e.g. 0.6"); }),
            "/ice/on | /ice/on: expected a number in m, got string \"yes\"; e.g. 0.6");
  EXPECT_EQ(error_of([&] { o.number("on", 0, JsonRange::any(), "", "a ratio"); }),
            "/ice/on | /ice/on: expected a number, got string \"yes\"; a ratio");
  EXPECT_EQ(error_of([&] { o.boolean("thickness", false); }),
            "/ice/thickness | /ice/thickness: expected true or false, got number 0.6");
  EXPECT_EQ(error_of([&] { o.string("name", "", false, "free text"); }),
            "/ice/name | /ice/name: expected a string, got number 3; free text");
  EXPECT_EQ(error_of([&] { o.vec<3>("origin", Eigen::Vector3d::Zero(), "m", "[x, y, z]"); }),
            "/ice/origin | /ice/origin: expected an array of 3 numbers in m, got array [1,\"x\"]; [x, y, z]");
  // A bad element is named by its index.
  EXPECT_EQ(error_of([&] { o.vec<2>("origin", Eigen::Vector2d::Zero(), "m", "[x, y]"); }),
            "/ice/origin/1 | /ice/origin/1: expected a finite number, got string \"x\"; [x, y]");
  EXPECT_EQ(error_of([&] { o.array("thickness", "points"); }),
            "/ice/thickness | /ice/thickness: expected an array of points, got number 0.6");
}

TEST(JsonReader, ValuesDefaultsAndRanges) {
  const JsonObject o = ice();
  EXPECT_EQ(o.number("thickness", 0, JsonRange::positive(), "m", ""), 0.6);
  EXPECT_EQ(o.number("absent", 7.5, JsonRange::positive(), "m", ""), 7.5);  // default, unchecked
  EXPECT_EQ(o.vec<3>("corner", Eigen::Vector3d::Zero(), "m", ""), Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(error_of([&] { o.number("neg", 0, JsonRange::positive(), "m", "e.g. 0.6"); }),
            "/ice/neg | /ice/neg: value -1 m is out of range: must be > 0 m; e.g. 0.6");
  EXPECT_TRUE(contains(error_of([&] { o.number("thickness", 0, {0.0, 0.5, true, true}, "", "h"); }),
                       "value 0.6 is out of range: must be > 0 and < 0.5; h"));
  EXPECT_TRUE(contains(error_of([&] { o.number("thickness", 0, {1.0, 2.0}, "Pa", "h"); }),
                       "must be >= 1 Pa and <= 2 Pa"));
  EXPECT_EQ(error_of([&] { o.number("absent", 0, JsonRange::positive(), "s", "e.g. 10", true, "simulated time, s"); }),
            "/ice/absent | /ice/absent: missing required field \"absent\" (simulated time, s); add it to the \"ice\" "
            "object");
  EXPECT_TRUE(contains(error_of([] { JsonObject(json::object(), "", {"name"}).missing("name", "an id"); }),
                       "/name | /name: missing required field \"name\" (an id); add it to the \"top level\" object"));
}

TEST(JsonReader, IntegersAreExactAndWhole) {
  const JsonObject o = ice();
  // A 64-bit seed survives exactly (a double would round it to 2^64).
  EXPECT_EQ(o.integer<std::uint64_t>("seed", 0, JsonRange::non_negative(), "", ""),
            std::numeric_limits<std::uint64_t>::max());
  EXPECT_EQ(o.integer<int>("count", 0, JsonRange::any(), "", ""), 20);  // 20.0 is whole
  EXPECT_EQ(o.integer<int>("absent", 8, JsonRange::any(), "", ""), 8);
  EXPECT_EQ(error_of([&] { o.integer<int>("half", 0, JsonRange::any(), "", "e.g. 64"); }),
            "/ice/half | /ice/half: expected a whole number, got 6.5; e.g. 64");
  EXPECT_TRUE(contains(error_of([&] { o.integer<std::uint64_t>("neg", 0, JsonRange::non_negative(), "", "s"); }),
                       "/ice/neg: value -1 is out of range: must be >= 0"));
  EXPECT_TRUE(contains(error_of([&] { o.integer<int>("big", 0, JsonRange::any(), "", "n"); }),
                       "/ice/big: value 3000000000 is out of range: must be >= -2.14748e+09 and <= 2.14748e+09"));
  EXPECT_TRUE(contains(error_of([&] { o.integer<int>("count", 0, {1.0, 10.0}, "steps", "n"); }),
                       "value 20.0 steps is out of range: must be >= 1 steps and <= 10 steps"));
  EXPECT_TRUE(contains(error_of([&] { o.integer<int>("on", 0, JsonRange::any(), "steps", "n"); }),
                       "expected a number in steps, got string \"yes\""));
}

TEST(JsonReader, ChoiceSuggestsTheNearestWord) {
  const JsonObject o = ice();
  EXPECT_EQ(error_of([&] { o.choice("model", "linear", {"linear", "hertz"}, "the contact law"); }),
            "/ice/model | /ice/model: \"hertzz\" is not allowed (did you mean \"hertz\"?); use one of \"linear\", "
            "\"hertz\"; the contact law");
  EXPECT_EQ(o.choice("absent", "linear", {"linear", "hertz"}), "linear");
  EXPECT_TRUE(contains(error_of([&] { o.choice("name", "linear", {"linear", "hertz"}); }),
                       "expected a string, got number 3; use one of \"linear\", \"hertz\""));
}

TEST(JsonReader, NullIsAWrongTypeOrAbsentAsTheReaderSays) {
  EXPECT_TRUE(contains(error_of([] { ice().number("none", 1.0, JsonRange::any(), "m", "h"); }),
                       "/ice/none: expected a number in m, got null; h"));
  const JsonObject lenient = ice(JsonNull::IsAbsent);
  EXPECT_FALSE(lenient.has("none"));
  EXPECT_EQ(lenient.number("none", 1.5, JsonRange::positive(), "m", "h"), 1.5);
  // Child readers keep the rule.
  const json j = {{"settle", {{"dt", nullptr}}}};
  const JsonObject parent(j, "", {"settle"}, "", JsonNull::IsAbsent);
  EXPECT_EQ(parent.object("settle", {"dt"}, "").number("dt", 0.25, JsonRange::positive(), "s", ""), 0.25);
  EXPECT_TRUE(contains(error_of([&] { parent.object("settle", {"dtt"}, ""); }), "/settle/dt | "));
}

TEST(JsonReader, TextAndFiles) {
  EXPECT_EQ(hs::parse_json_text("{\"a\": [1, 2]}", "x.json").at("a").size(), 2u);
  const std::string syntax = error_of([] { hs::parse_json_text("{\n  \"a\": 1,\n  \"b\": 2,\n}", "x.json"); });
  EXPECT_TRUE(contains(syntax, "x.json | x.json: invalid JSON at line 4, column 1")) << syntax;
  EXPECT_TRUE(contains(syntax, "trailing comma")) << syntax;
  const std::string missing = error_of([] { hs::read_json_file("/nonexistent/dir/x.json", "ridge scene file"); });
  EXPECT_TRUE(contains(missing, "/nonexistent/dir/x.json | /nonexistent/dir/x.json: cannot open the ridge scene file"))
      << missing;
  const auto f = std::filesystem::temp_directory_path() / "hs_test_json_reader.json";
  std::ofstream(f) << R"({"thickness": 0.9})";
  EXPECT_EQ(hs::read_json_file(f.string()).at("thickness"), 0.9);
  std::filesystem::remove(f);
}

// Issue 14, defect 9: found while parsing, before the document is built, at their JSON pointer.
TEST(JsonReaderGuards, DeepNestingIsRefusedNotACrash) {
  // 100,000 levels used to parse, then overflow the stack when the error was formatted.
  const std::string deep = "{\"name\": \"x\", \"time\": " + std::string(100000, '[') + std::string(100000, ']') + "}";
  const std::string e = error_of([&] { hs::parse_json_text(deep, "deep.json"); });
  EXPECT_NE(e.find("nesting deeper than 100"), std::string::npos) << e.substr(0, 300);
  EXPECT_EQ(e.rfind("/time/0/0", 0), 0u) << e.substr(0, 300);  // the path says where
  // Exactly the limit is fine.
  const std::size_t n = hs::kJsonMaxDepth;
  EXPECT_NO_THROW(hs::parse_json_text(std::string(n, '[') + std::string(n, ']'), "ok.json"));
  EXPECT_THROW(hs::parse_json_text(std::string(n + 1, '[') + std::string(n + 1, ']'), "no.json"), InputError);
}

TEST(JsonReaderGuards, DuplicateKeysAreRefusedWithTheirPath) {
  const std::string e =
      error_of([] { hs::parse_json_text(R"({"time": {"dt": 1e-4, "duration": 1, "dt": 2e-4}})", "dup.json"); });
  EXPECT_EQ(e.rfind("/time/dt | ", 0), 0u) << e;
  EXPECT_NE(e.find("duplicate key \"dt\""), std::string::npos) << e;
  // In an array of objects the index is part of the path; equal keys in different objects are fine.
  const std::string e2 =
      error_of([] { hs::parse_json_text(R"({"walls": [{"name": "a"}, {"name": "b", "name": "c"}]})", "dup.json"); });
  EXPECT_EQ(e2.rfind("/walls/1/name | ", 0), 0u) << e2;
  EXPECT_NO_THROW(hs::parse_json_text(R"({"a": {"x": 1}, "b": {"x": 1}, "c": [{"x": 1}, {"x": 2}]})", "ok.json"));
}

TEST(JsonReaderGuards, NumbersBeyondADoubleAreInputErrorsWithTheirPath) {
  const std::string e =
      error_of([] { hs::parse_json_text(R"({"name": "x", "time": {"duration": 1e400}})", "big.json"); });
  EXPECT_EQ(e.rfind("/time/duration | ", 0), 0u) << e;
  EXPECT_NE(e.find("1e400"), std::string::npos) << e;
  const std::string e2 = error_of([] { hs::parse_json_text(R"({"walls": [{"point": [0, -1e999, 0]}]})", "big.json"); });
  EXPECT_EQ(e2.rfind("/walls/0/point/1 | ", 0), 0u) << e2;
}
