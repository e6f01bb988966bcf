#include "io/h5_handle.h"

#include <stdexcept>

namespace hs::io::h5 {

namespace {

herr_t collect_error(unsigned n, const H5E_error2_t* err, void* out) {
  auto& text = *static_cast<std::string*>(out);
  if (n >= 4) return 0;  // the outermost few frames say enough
  if (!text.empty()) text += "; ";
  text += err->func_name ? err->func_name : "?";
  text += ": ";
  text += err->desc ? err->desc : "?";
  return 0;
}

}  // namespace

std::string error_stack_text() {
  std::string text;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_DOWNWARD, collect_error, &text);
  H5Eclear2(H5E_DEFAULT);
  return text;
}

void fail(const char* call, const std::string& object, const std::string& file) {
  std::string msg = std::string("HDF5 ") + call + " failed for '" + object + "' in '" + file + "'";
  const std::string detail = error_stack_text();
  if (!detail.empty()) msg += " (" + detail + ")";
  throw std::runtime_error(msg);
}

}  // namespace hs::io::h5
