// "Did you mean ...?" suggestions for unknown JSON keys and CLI words.
//
// did_you_mean(key, allowed) returns "" or ` (did you mean "x"?)`, where x is the allowed
// word closest to `key` by Levenshtein distance (case-insensitive), accepted when the
// distance is at most max(2, |key|/3). Ties go to the word listed first. Append the result
// to an error message: "unknown key \"thicknes\"" + did_you_mean(...).
#pragma once

#include <algorithm>
#include <cctype>
#include <cstddef>
#include <string>
#include <vector>

namespace hs {

/// Levenshtein edit distance (insertions, deletions, substitutions all cost 1),
/// comparing characters case-insensitively. O(|a| |b|) time, O(|b|) memory.
inline std::size_t edit_distance(const std::string& a, const std::string& b) {
  const auto lower = [](char ch) {
    return static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  };
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];  // row[i-1][j-1]
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];  // row[i-1][j]
      const std::size_t substitute = diagonal + (lower(a[i - 1]) == lower(b[j - 1]) ? 0 : 1);
      row[j] = std::min({above + 1, row[j - 1] + 1, substitute});
      diagonal = above;
    }
  }
  return row[b.size()];
}

/// ` (did you mean "x"?)` for the closest word x of `allowed`, or "" if none is close.
inline std::string did_you_mean(const std::string& key, const std::vector<std::string>& allowed) {
  const std::size_t limit = std::max<std::size_t>(2, key.size() / 3);
  const std::string* best = nullptr;
  std::size_t best_distance = limit + 1;
  for (const std::string& word : allowed) {
    const std::size_t d = edit_distance(key, word);
    if (d < best_distance) {
      best_distance = d;
      best = &word;
    }
  }
  if (best == nullptr) return "";
  return " (did you mean \"" + *best + "\"?)";
}

}  // namespace hs
