// STUDY.json (src/study/study.h): the members a study lists, and each bad field refused with an
// InputError at its JSON pointer that says the fix.
#include <gtest/gtest.h>

#include "common/error.h"
#include "json/reader.h"
#include "study/study.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>

namespace fs = std::filesystem;
using hs::study::parse_study;

namespace {

/// A study file's directory with a base scene "base.json" in it (its content is not read here).
fs::path study_dir() {
  static const fs::path d = [] {
    const fs::path p = fs::temp_directory_path() / ("hs_test_study_def_" + std::to_string(::getpid()));
    fs::create_directories(p);
    std::ofstream(p / "base.json") << "{}";
    return p;
  }();
  return d;
}

hs::study::StudyDef parse(const std::string& text) {
  return parse_study(hs::parse_json_text(text, "s.json"), study_dir() / "s.json");
}

/// The InputError of parsing `text`: its path and message ("" when none is thrown).
std::pair<std::string, std::string> error_of(const std::string& text) {
  try {
    parse(text);
  } catch (const hs::InputError& e) {
    return {e.path(), e.what()};
  }
  return {"", ""};
}

}  // namespace

// Variants x seeds, in name order, each with the study's "set" first, then its own, then its seed;
// ids and outputs as docs/study.md gives them; output_dir beside the study file by default.
TEST(StudyDef, VariantsTimesSeedsInNameOrder) {
  const auto d = parse(R"({"base": "base.json", "seeds": [3, 1], "set": ["time.duration=0.1"],
                           "variants": {"soft": ["material.youngs_modulus=1e7"], "hard": []}, "reference": "hard"})");
  const auto m = d.members();
  ASSERT_EQ(m.size(), 4u);
  EXPECT_EQ(m[0].id(), "hard/seed3");
  EXPECT_EQ(m[1].id(), "hard/seed1");
  EXPECT_EQ(m[2].id(), "soft/seed3");
  EXPECT_EQ(m[2].output_rel(), fs::path("soft/seed3.h5"));
  EXPECT_EQ(m[2].overrides, (std::vector<std::string>{"time.duration=0.1", "material.youngs_modulus=1e7", "seed=3"}));
  EXPECT_EQ(d.output_dir, study_dir() / "s");
  EXPECT_EQ(d.base_scene, study_dir() / "base.json");
  EXPECT_EQ(d.mpi_ranks, 1);
}

// A count of seeds is 1..n; a grid crosses its fields (and the variants) into named variants.
TEST(StudyDef, SeedCountAndGridCrossing) {
  const auto d = parse(R"({"base": "base.json", "seeds": 2, "variants": {"a": ["x=1"]},
                           "grid": {"material.particle_diameter": [0.2, 0.25], "time.alpha": [0.1, 0.2, 0.3]}})");
  EXPECT_EQ(d.seeds, (std::vector<std::int64_t>{1, 2}));
  ASSERT_EQ(d.variants.size(), 6u);
  EXPECT_EQ(d.variants[0].name, "a,material.particle_diameter=0.2,time.alpha=0.1");
  EXPECT_EQ(d.variants[0].overrides,
            (std::vector<std::string>{"x=1", "material.particle_diameter=0.2", "time.alpha=0.1"}));
  EXPECT_EQ(d.variants[5].name, "a,material.particle_diameter=0.25,time.alpha=0.3");
  EXPECT_EQ(d.members().size(), 12u);
  const auto g = parse(R"({"base": "base.json", "seeds": 1, "grid": {"material.stiffness_model": ["calibrated"]}})");
  EXPECT_EQ(g.variants[0].name, "material.stiffness_model=calibrated");
  EXPECT_EQ(parse(R"({"base": "base.json", "seeds": 1})").variants[0].name, "base");
}

// "variant_seeds" gives the named variants their own seeds (count or list); the others run "seeds".
TEST(StudyDef, VariantSeedsGiveAVariantItsOwnSeeds) {
  const auto d = parse(R"({"base": "base.json", "seeds": 3, "variants": {"ref": [], "a": ["x=1"], "b": ["x=2"]},
                           "variant_seeds": {"ref": 5, "b": [7, 2]}, "reference": "ref"})");
  std::vector<std::string> ids;
  for (const auto& m : d.members()) ids.push_back(m.id());
  EXPECT_EQ(ids, (std::vector<std::string>{"a/seed1", "a/seed2", "a/seed3", "b/seed7", "b/seed2", "ref/seed1",
                                           "ref/seed2", "ref/seed3", "ref/seed4", "ref/seed5"}));
  EXPECT_EQ(d.members()[3].overrides, (std::vector<std::string>{"x=2", "seed=7"}));
  EXPECT_EQ(d.seeds, (std::vector<std::int64_t>{1, 2, 3}));
}

// Every bad field is named by its pointer, with what is wrong and the fix.
TEST(StudyDef, BadFieldsAreNamedWithTheFix) {
  const auto check = [](const std::string& text, const std::string& path, const std::string& words) {
    const auto [p, msg] = error_of(text);
    EXPECT_EQ(p, path) << text << "\n" << msg;
    EXPECT_NE(msg.find(words), std::string::npos) << text << "\n" << msg;
  };
  check(R"({"seeds": 1})", "/base", "missing required field \"base\"");
  check(R"({"base": "nothere.json", "seeds": 1})", "/base", "does not exist");
  check(R"({"base": "base.json"})", "/seeds", "missing required field \"seeds\"");
  check(R"({"base": "base.json", "seeds": 0})", "/seeds", "out of range");
  check(R"({"base": "base.json", "seeds": [1, 1]})", "/seeds/1", "listed twice");
  check(R"({"base": "base.json", "seeds": [1, -2]})", "/seeds/1", "whole number >= 0");
  check(R"({"base": "base.json", "seeds": "3"})", "/seeds", "expected a count");
  check(R"({"base": "base.json", "seeds": 1, "varients": {}})", "/varients", "did you mean \"variants\"");
  check(R"({"base": "base.json", "seeds": 1, "variants": {"a": ["ice.thickness"]}})", "/variants/a/0",
        "\"path=value\"");
  check(R"({"base": "base.json", "seeds": 1, "variants": {"a": "x=1"}})", "/variants/a", "expected an array");
  check(R"({"base": "base.json", "seeds": 1, "variants": {"a": ["seed=4"]}})", "/variants/a/0", "\"seeds\"");
  check(R"({"base": "base.json", "seeds": 1, "variants": {"a/b": []}})", "/variants/a~1b", "directory name");
  check(R"({"base": "base.json", "seeds": 1, "grid": {"ice.thickness": []}})", "/grid/ice.thickness",
        "non-empty list");
  check(R"({"base": "base.json", "seeds": 1, "variants": {"soft": []}, "reference": "sfot"})", "/reference",
        "did you mean \"soft\"");
  check(R"({"base": "base.json", "seeds": 1, "mpi_ranks": 0})", "/mpi_ranks", "out of range");
  check(R"({"base": "base.json", "seeds": 1, "variants": {"soft": []}, "variant_seeds": {"sfot": 5}})",
        "/variant_seeds/sfot", "did you mean \"soft\"");
  check(R"({"base": "base.json", "seeds": 1, "variant_seeds": {"base": [2, 2]}})", "/variant_seeds/base/1",
        "listed twice");
  check(R"({"base": "base.json", "seeds": 1, "variant_seeds": {"base": 0}})", "/variant_seeds/base", "out of range");
  check(R"({"base": "base.json", "seeds": 1, "variant_seeds": [5]})", "/variant_seeds", "expected an object");
  check(R"({"base": "base.json", "seeds": 1, "grid": {"structure.mesh": ["a/b", "a_b"]}})", "/grid",
        "two variants are named \"structure.mesh=a_b\"");
}
