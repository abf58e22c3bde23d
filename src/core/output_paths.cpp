#include "core/output_paths.h"

#include "core/atomic_file.h"

#include <fmt/core.h>

#include <system_error>

namespace microsim {

namespace fs = std::filesystem;

namespace {

bool exists_quietly(const fs::path& p) {
  std::error_code ec;
  return fs::exists(p, ec) && !ec;
}

// The weakly_canonical form of the absolute path (weakly_canonical keeps a relative path relative when
// none of it exists: "o.exr" and "./o.exr" would differ), or the lexically normal absolute path if the
// filesystem cannot tell.
fs::path canonical_form(const fs::path& p) {
  std::error_code ec;
  const fs::path absolute = fs::absolute(p, ec);
  fs::path c = fs::weakly_canonical(absolute, ec);
  if (ec) c = absolute.lexically_normal();
  return c;
}

std::string spelled(const PathOption& p) { return fmt::format("{} '{}'", p.option, p.path.string()); }

}  // namespace

bool same_file(const fs::path& a, const fs::path& b) {
  const bool ea = exists_quietly(a), eb = exists_quietly(b);
  if (ea != eb) return false;
  if (ea) {
    std::error_code ec;
    const bool same = fs::equivalent(a, b, ec);
    return !ec && same;
  }
  return canonical_form(a) == canonical_form(b);
}

void check_output_paths(const std::vector<PathOption>& inputs, const std::vector<PathOption>& outputs) {
  for (std::size_t k = 0; k < outputs.size(); ++k) {
    const PathOption& out = outputs[k];
    if (out.path.empty()) continue;
    for (const PathOption& in : inputs) {
      if (in.path.empty() || !same_file(out.path, in.path)) continue;
      throw OutputPathError(fmt::format("{} is the same file as the input {}: an output must not overwrite an input "
                                        "(nothing written)",
                                        spelled(out), spelled(in)));
    }
    for (std::size_t e = 0; e < k; ++e) {
      const PathOption& earlier = outputs[e];
      if (earlier.path.empty() || !same_file(out.path, earlier.path)) continue;
      throw OutputPathError(fmt::format("{} and {} are the same file: each output needs its own path (nothing written)",
                                        spelled(earlier), spelled(out)));
    }
  }
}

void check_writable(const fs::path& path) {
  std::error_code ec;
  if (path.empty()) throw OutputPathError("output path is empty");
  if (fs::is_directory(path, ec)) throw OutputPathError(fmt::format("output '{}' is a directory", path.string()));
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  if (!fs::is_directory(dir, ec))
    throw OutputPathError(fmt::format("cannot write '{}': directory '{}' does not exist", path.string(), dir.string()));
  try {
    const TemporaryFile probe(path);  // a new file beside `path`, removed again
  } catch (const FileWriteError&) {
    throw OutputPathError(fmt::format("cannot write '{}': directory '{}' is not writable", path.string(), dir.string()));
  }
}

}  // namespace microsim
