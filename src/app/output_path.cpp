#include "app/output_path.h"

#include "common/error.h"

#include <unistd.h>

#include <filesystem>
#include <system_error>

namespace hs::app {

namespace {

namespace fs = std::filesystem;

/// Same file: by inode when both exist (hard links, bind mounts), else by the resolved path
/// (weakly_canonical follows every symlink of the part that exists).
bool same_file(const fs::path& a, const fs::path& b) {
  std::error_code ec;
  if (fs::exists(a, ec) && fs::exists(b, ec)) {
    const bool eq = fs::equivalent(a, b, ec);
    if (!ec) return eq;
  }
  const fs::path ca = fs::weakly_canonical(fs::absolute(a), ec);
  if (ec) return false;
  const fs::path cb = fs::weakly_canonical(fs::absolute(b), ec);
  return !ec && ca == cb;
}

}  // namespace

void check_output_path(const std::string& output, const std::string& companion,
                       const std::vector<InputFile>& inputs) {
  if (output.empty()) throw InputError("-o", "the output path is empty; give a file name, e.g. -o run.h5");
  for (const InputFile& in : inputs) {
    if (in.path.empty()) continue;
    for (const std::string* out : {&output, &companion}) {
      if (out->empty() || !same_file(*out, in.path)) continue;
      const std::string which = out == &output ? "the output file" : "the output's index file '" + *out + "'";
      throw InputError(output, which + " would overwrite " + in.what + " '" + in.path +
                                   "' (the same file); choose another output path with -o");
    }
  }
  std::error_code ec;
  const fs::path p = fs::absolute(output, ec);
  if (fs::is_directory(p, ec))
    throw InputError(output, "the output path is a directory; give a file name with -o, e.g. -o " +
                                 (fs::path(output) / "run.h5").string());
  const fs::path dir = p.parent_path();
  if (!fs::is_directory(dir, ec))
    throw InputError(output, "the output directory '" + dir.string() +
                                 "' does not exist; create it (mkdir -p) or choose another path with -o");
  if (::access(dir.c_str(), W_OK | X_OK) != 0)
    throw InputError(output, "the output directory '" + dir.string() +
                                 "' is not writable; choose another path with -o or fix its permissions");
}

}  // namespace hs::app
