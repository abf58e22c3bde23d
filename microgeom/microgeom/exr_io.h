// microgeom: a small OpenEXR 3 helper for float images with named channels and string attributes.
//
// Used for heightmaps, normal maps and histogram images. Every channel is stored as 32-bit FLOAT with
// lossless ZIP compression, so a heightfield written and read back is bit-identical. Pixels are row-major:
// data[y * width + x], y = 0 is the first scanline (the top of the data window).
//
// Writing is atomic: the image goes to a temporary file in the destination directory, which is renamed
// over the destination only once complete; on failure nothing is left behind.
#pragma once

#include <deque>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace microgeom {

struct ExrChannel {
  std::string name;
  std::vector<float> data;  // row-major, width * height
};

struct ExrImage {
  int width = 0, height = 0;
  // On read, channels come in the file's order (OpenEXR sorts channel names alphabetically).
  // A deque, not a vector: appending a channel never moves the others, so the reference that
  // add_channel returns stays valid while further channels are added.
  std::deque<ExrChannel> channels;
  std::map<std::string, std::string> attributes;  // string attributes only

  // The channel of that exact name, or nullptr.
  const ExrChannel* find(std::string_view name) const;
  ExrChannel* find(std::string_view name);
  // Appends a channel of width * height zeros and returns it (throws if the name is taken). The reference
  // stays valid until the channel itself is removed, whatever is added after it.
  ExrChannel& add_channel(std::string name);
};

// Writes FLOAT channels and string attributes atomically (temp file in the same directory, then rename).
// Throws std::runtime_error naming the path on failure (empty image, a channel whose size is not
// width * height, duplicate or empty channel names, an attribute name that clashes with a standard EXR
// attribute, I/O errors); leaves nothing behind.
void write_exr(const std::filesystem::path& path, const ExrImage& image);

// Reads every channel as float (HALF and UINT channels are converted by OpenEXR) and every string
// attribute. Throws std::runtime_error naming the path (missing file, not an EXR, subsampled channels,
// truncated data).
ExrImage read_exr(const std::filesystem::path& path);

}  // namespace microgeom
