// microgeom: a small OpenEXR 3 helper for float images with named channels and string attributes.
//
// Used for heightmaps, normal maps and histogram images. Every channel is stored as 32-bit FLOAT with
// lossless ZIP compression, so a heightfield written and read back is bit-identical. Pixels are row-major:
// data[y * width + x], y = 0 is the first scanline (the top of the data window).
//
// Writing is atomic: the image goes to a temporary file in the destination directory, which is renamed
// over the destination only once complete; on failure nothing is left behind.
#pragma once

#include <cstdint>
#include <deque>
#include <filesystem>
#include <map>
#include <span>
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

// The most float data read_exr decodes (width x height x channels x 4 bytes): 2 GiB, e.g. 16384 x 16384
// pixels x 2 channels (the largest heightmap `surface build` writes, 8192 x 8192, is 256 MiB).
inline constexpr std::uint64_t kMaxExrDecodedBytes = std::uint64_t(2) << 30;

// Reads every channel as float (HALF and UINT channels are converted by OpenEXR) and every string
// attribute. Throws std::runtime_error naming the path (missing file, not an EXR, a multi-part or deep
// file, subsampled channels, truncated data). The sizes the header claims are checked before anything
// is allocated or decoded: the decoded data, and one tile or chunk of scan lines, against
// `max_decoded_bytes` (the message states the claim and the limit), and the chunk offset table and (for
// uncompressed, RLE, ZIP and PXR24 files) the pixel data against the size of the file. std::bad_alloc passes through unchanged (out of memory).
ExrImage read_exr(const std::filesystem::path& path, std::uint64_t max_decoded_bytes = kMaxExrDecodedBytes);
// The same for the bytes of an EXR file in memory; `name` stands for the path in messages.
ExrImage read_exr_memory(std::span<const char> bytes, const std::string& name,
                         std::uint64_t max_decoded_bytes = kMaxExrDecodedBytes);

}  // namespace microgeom
