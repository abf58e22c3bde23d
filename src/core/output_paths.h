// microsim: the checks of a command's outputs, made before any work. check_output_paths: the outputs lose
// no file: an output must not be one of the inputs (writing it would destroy the
// input) and no two outputs may be the same file (one would silently replace the other). check_writable:
// each output can be created (its directory exists and is writable, it is not a directory), so that a bad
// output fails before a long run, not after it.
//
// "The same file" is decided by the filesystem, not by spelling: two existing paths are the same file when
// std::filesystem::equivalent says so (same device and inode: hard links, symbolic links, and spellings
// such as ./a/../in.txt); a path that does not exist yet is compared by its weakly_canonical form.
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace microsim {

// A path given to a command, with the option that named it ("--json", "--from", or the positional name).
// An empty path (option not given) is ignored.
struct PathOption {
  std::string option;
  std::filesystem::path path;
};

// An output path that cannot be used: two paths of a command would name the same file (the message names
// both options and both paths), or an output cannot be created (the message names the path).
struct OutputPathError : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

// Whether `a` and `b` name the same file: equivalent() when both exist, else the same weakly_canonical
// path when neither exists (an existing and a missing path are different files).
bool same_file(const std::filesystem::path& a, const std::filesystem::path& b);

// Throws OutputPathError when an output is the same file as an input or as another output.
void check_output_paths(const std::vector<PathOption>& inputs, const std::vector<PathOption>& outputs);

// Throws OutputPathError unless a file can be created at `path`: not empty, not a directory, its directory
// exists and is writable (a probe file is created beside it and removed). An existing file at `path` is
// fine: the atomic writer replaces it by rename(), which needs only the directory to be writable.
void check_writable(const std::filesystem::path& path);

}  // namespace microsim
