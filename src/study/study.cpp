#include "study/study.h"

#include "common/did_you_mean.h"
#include "common/error.h"
#include "json/reader.h"

#include <algorithm>
#include <cmath>
#include <set>

namespace hs::study {

namespace fs = std::filesystem;

namespace {

const std::vector<std::string> kKeys = {"description", "base",   "seeds",      "set",
                                        "variants",    "grid",   "reference",  "primary_metric",
                                        "mpi_ranks",   "mpirun", "output_dir", "windows",
                                        "variant_seeds"};

/// A variant name is a directory name: letters, digits and "_-.=,+" (no "/", not "." or "..").
void check_name(const std::string& name, const std::string& ptr) {
  bool ok = !name.empty() && name[0] != '.' && name.size() <= 200;
  for (const char c : name)
    ok = ok && (std::isalnum(static_cast<unsigned char>(c)) || std::string_view("_-.=,+").find(c) != std::string::npos);
  if (!ok)
    throw InputError(ptr, "variant name \"" + name +
                              "\" is not a plain directory name: use letters, digits and _-.=,+ (not first a dot), "
                              "e.g. \"soft\" or \"D0.2\"");
}

/// A list of "path=value" strings at `ptr`.
std::vector<std::string> overrides(const nlohmann::json& v, const std::string& ptr) {
  if (!v.is_array())
    throw InputError(ptr, "expected an array of --set overrides (\"path=value\" strings), got " + json_got(v) +
                              "; e.g. [\"material.particle_diameter=0.25\"]");
  std::vector<std::string> out;
  for (std::size_t k = 0; k < v.size(); ++k) {
    const nlohmann::json& e = v[k];
    const std::string p = ptr + "/" + std::to_string(k);
    if (!e.is_string() || e.get<std::string>().find('=') == std::string::npos ||
        e.get<std::string>().front() == '=')
      throw InputError(p, "expected a \"path=value\" string as for `hybridsim run --set`, got " + json_got(e) +
                              "; e.g. \"ice.thickness=0.9\"");
    if (e.get<std::string>().rfind("seed=", 0) == 0)
      throw InputError(p, "the seed is the study's: list it in \"seeds\", not as an override");
    out.push_back(e.get<std::string>());
  }
  return out;
}

/// A seed list at `ptr`: a count n (the seeds 1..n) or a non-empty list of distinct integers >= 0.
std::vector<std::int64_t> seed_list(const nlohmann::json& v, const std::string& ptr) {
  std::vector<std::int64_t> out;
  if (v.is_number()) {
    const double n = v.get<double>();
    if (!(n >= 1 && n <= 100000) || n != std::floor(n))
      throw InputError(ptr, "value " + json_show(v) +
                                " out of range: a count n runs seeds 1..n, a whole number from 1 to 100000, e.g. 3");
    for (std::int64_t k = 1; k <= static_cast<std::int64_t>(n); ++k) out.push_back(k);
    return out;
  }
  if (!v.is_array() || v.empty())
    throw InputError(ptr, "expected a count (e.g. 3 for seeds 1, 2, 3) or a non-empty list of integers, got " +
                              json_got(v));
  std::set<std::int64_t> seen;
  for (std::size_t k = 0; k < v.size(); ++k) {
    const std::string p = ptr + "/" + std::to_string(k);
    if (!v[k].is_number_integer() || v[k].get<std::int64_t>() < 0)
      throw InputError(p, "expected a whole number >= 0, got " + json_got(v[k]));
    if (!seen.insert(v[k].get<std::int64_t>()).second)
      throw InputError(p, "seed " + json_show(v[k]) + " is listed twice; each seed is one member of every variant");
    out.push_back(v[k].get<std::int64_t>());
  }
  return out;
}

std::vector<std::int64_t> seeds(const JsonObject& o) {
  if (!o.has("seeds")) o.missing("seeds", "the seeds of every variant: a list of integers, or a count n for 1..n");
  return seed_list(o.raw("seeds"), "/seeds");
}

/// "variant_seeds": variant name -> its own seeds; every other variant keeps the study's.
void variant_seeds(const JsonObject& o, std::vector<Variant>& variants, const std::vector<std::int64_t>& all) {
  for (Variant& v : variants) v.seeds = all;
  if (!o.has("variant_seeds")) return;
  const nlohmann::json& vs = o.raw("variant_seeds");
  if (!vs.is_object())
    throw InputError("/variant_seeds", "expected an object of variant name -> seeds (a count or a list), got " +
                                           json_got(vs) + "; e.g. {\"reference\": 5}");
  std::vector<std::string> names;
  for (const Variant& v : variants) names.push_back(v.name);
  for (const auto& [name, list] : vs.items()) {
    const std::string p = "/variant_seeds/" + json_pointer_token(name);
    const auto it = std::find(names.begin(), names.end(), name);
    if (it == names.end()) {
      std::string known;
      for (const auto& n : names) known += (known.empty() ? "" : ", ") + n;
      throw InputError(p, "\"" + name + "\" is not a variant of the study" + did_you_mean(name, names) +
                              "; the variants are: " + known);
    }
    variants[static_cast<std::size_t>(it - names.begin())].seeds = seed_list(list, p);
  }
}

/// The grid's points in name order of the fields, each as (name, overrides): "f=v,g=w".
std::vector<Variant> grid_points(const JsonObject& o) {
  std::vector<Variant> pts{{"", {}, {}}};
  if (!o.has("grid")) return pts;
  const nlohmann::json& g = o.raw("grid");
  if (!g.is_object() || g.empty())
    throw InputError("/grid", "expected an object of scene field -> list of values, got " + json_got(g) +
                                  "; e.g. {\"material.particle_diameter\": [0.2, 0.25]}");
  for (const auto& [field, values] : g.items()) {
    const std::string p = "/grid/" + json_pointer_token(field);
    if (!values.is_array() || values.empty())
      throw InputError(p, "expected a non-empty list of values of " + field + ", got " + json_got(values));
    std::vector<Variant> next;
    for (const Variant& v : pts)
      for (std::size_t k = 0; k < values.size(); ++k) {
        const nlohmann::json& x = values[k];
        if (!x.is_primitive() || x.is_null())
          throw InputError(p + "/" + std::to_string(k), "expected a number, string or true/false, got " + json_got(x));
        const std::string text = x.is_string() ? x.get<std::string>() : x.dump();
        std::string shown = text;
        for (char& c : shown)
          if (c == '/' || c == ' ') c = '_';
        next.push_back({v.name + (v.name.empty() ? "" : ",") + field + "=" + shown, v.overrides, {}});
        next.back().overrides.push_back(field + "=" + text);
      }
    pts = std::move(next);
  }
  return pts;
}

std::vector<Variant> variants(const JsonObject& o) {
  std::vector<Variant> named;
  if (o.has("variants")) {
    const nlohmann::json& v = o.raw("variants");
    if (!v.is_object() || v.empty())
      throw InputError("/variants", "expected an object of variant name -> list of --set overrides, got " +
                                        json_got(v) + "; e.g. {\"soft\": [\"material.youngs_modulus=1e7\"]}");
    for (const auto& [name, list] : v.items()) {
      const std::string p = "/variants/" + json_pointer_token(name);
      check_name(name, p);
      named.push_back({name, overrides(list, p), {}});
    }
  } else {
    named.push_back({"", {}, {}});
  }
  std::vector<Variant> out;
  const std::vector<Variant> pts = grid_points(o);
  for (const Variant& a : named)
    for (const Variant& b : pts) {
      Variant v{a.name + (a.name.empty() || b.name.empty() ? "" : ",") + b.name, a.overrides, {}};
      v.overrides.insert(v.overrides.end(), b.overrides.begin(), b.overrides.end());
      if (v.name.empty()) v.name = "base";
      check_name(v.name, o.has("grid") ? "/grid" : "/variants");
      out.push_back(std::move(v));
    }
  return out;
}

}  // namespace

std::vector<Member> StudyDef::members() const {
  std::vector<Member> out;
  for (const Variant& v : variants)
    for (const std::int64_t s : v.seeds) {
      Member m{v.name, s, common};
      m.overrides.insert(m.overrides.end(), v.overrides.begin(), v.overrides.end());
      m.overrides.push_back("seed=" + std::to_string(s));
      out.push_back(std::move(m));
    }
  return out;
}

StudyDef parse_study(const nlohmann::json& doc, const fs::path& study_file) {
  const JsonObject o(doc, "", kKeys, "a study file is a JSON object; see docs/study.md");
  StudyDef d;
  d.study_file = study_file;
  d.name = study_file.stem().string();
  const fs::path dir = study_file.parent_path();
  const std::string base = o.string("base", "", true, "the base scene file, relative to the study file");
  d.base_scene = dir / base;
  if (!fs::is_regular_file(d.base_scene))
    throw InputError("/base", "scene file '" + d.base_scene.string() +
                                  "' does not exist; \"base\" is a path relative to the study file's directory");
  d.seeds = seeds(o);
  if (o.has("set")) d.common = overrides(o.raw("set"), "/set");
  d.variants = variants(o);
  std::vector<std::string> names;
  for (const Variant& v : d.variants) {
    if (std::find(names.begin(), names.end(), v.name) != names.end())
      throw InputError(o.has("grid") ? "/grid" : "/variants",
                       "two variants are named \"" + v.name + "\" (a grid value's \"/\" and spaces are written "
                       "\"_\" in the name); make the values or the variant names differ");
    names.push_back(v.name);
  }
  variant_seeds(o, d.variants, d.seeds);
  d.reference = o.string("reference", "");
  if (!d.reference.empty() && std::find(names.begin(), names.end(), d.reference) == names.end())
    throw InputError("/reference", "\"" + d.reference + "\" is not a variant of the study" +
                                       did_you_mean(d.reference, names) + "; the variants are: " + [&] {
                                         std::string s;
                                         for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
                                         return s;
                                       }());
  d.primary_metric = o.string("primary_metric", "");
  d.mpi_ranks = o.integer<int>("mpi_ranks", 1, {1, 100000}, "", "the MPI ranks of each member, e.g. 4");
  d.mpirun = o.string("mpirun", "mpirun");
  d.output_dir = dir / o.string("output_dir", d.name);
  if (o.has("windows")) d.windows = o.raw("windows");
  return d;
}

StudyDef load_study_file(const fs::path& study_file) {
  return parse_study(read_json_file(study_file.string(), "study file"), study_file);
}

}  // namespace hs::study
