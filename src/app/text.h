// Number formatting for the command line's messages.
#pragma once

#include <cmath>
#include <cstdio>
#include <iomanip>
#include <sstream>
#include <string>

namespace hs::app {

/// "m:ss" or "h:mm:ss"; "?" for a negative or non-finite duration.
inline std::string duration_text(double s) {
  if (!std::isfinite(s) || s < 0) return "?";
  const long t = std::lround(s);
  char buf[64];
  if (t >= 3600)
    std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", t / 3600, (t / 60) % 60, t % 60);
  else
    std::snprintf(buf, sizeof buf, "%ld:%02ld", t / 60, t % 60);
  return buf;
}

/// x with `prec` significant digits.
inline std::string sci(double x, int prec = 3) {
  std::ostringstream s;
  s << std::setprecision(prec) << x;
  return s.str();
}

}  // namespace hs::app
