#include "microgeom/exr_io.h"

#include "core/strict_parse.h"
#include "core/atomic_file.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStdIO.h>
#include <ImfStringAttribute.h>
#include <ImfTileDescriptionAttribute.h>
#include <ImfVersion.h>
#include <IexBaseExc.h>

#include <fmt/core.h>

#include <climits>
#include <cmath>
#include <cstring>
#include <memory>
#include <exception>
#include <set>
#include <stdexcept>
#include <system_error>

namespace microgeom {

const ExrChannel* ExrImage::find(std::string_view name) const {
  for (const auto& c : channels)
    if (c.name == name) return &c;
  return nullptr;
}

ExrChannel* ExrImage::find(std::string_view name) {
  for (auto& c : channels)
    if (c.name == name) return &c;
  return nullptr;
}

ExrChannel& ExrImage::add_channel(std::string name) {
  if (find(name)) throw std::runtime_error(fmt::format("EXR image: duplicate channel name '{}'", name));
  channels.push_back({std::move(name), std::vector<float>(std::size_t(width) * std::size_t(height), 0.0f)});
  return channels.back();
}

namespace {

// Attribute names the EXR header itself defines: a user string attribute of that name would clash.
bool is_standard_attribute(const std::string& name) {
  static const std::set<std::string> names = {
      "channels", "compression", "dataWindow", "displayWindow", "lineOrder", "pixelAspectRatio",
      "screenWindowCenter", "screenWindowWidth", "tiles", "type", "name", "version", "chunkCount"};
  return names.count(name) != 0;
}

}  // namespace

void write_exr(const std::filesystem::path& path, const ExrImage& image) {
  auto fail = [&](const std::string& why) {
    return std::runtime_error(fmt::format("cannot write EXR '{}': {}", path.string(), why));
  };
  if (image.width <= 0 || image.height <= 0)
    throw fail(fmt::format("empty image ({} x {})", image.width, image.height));
  if (image.channels.empty()) throw fail("no channels");
  const std::size_t texels = std::size_t(image.width) * std::size_t(image.height);
  std::set<std::string> seen;
  for (const auto& c : image.channels) {
    if (c.name.empty()) throw fail("a channel has an empty name");
    if (!seen.insert(c.name).second) throw fail(fmt::format("duplicate channel '{}'", c.name));
    if (c.data.size() != texels)
      throw fail(fmt::format("channel '{}' has {} values, expected {} x {} = {}", c.name, c.data.size(),
                             image.width, image.height, texels));
  }
  for (const auto& [key, value] : image.attributes)
    if (key.empty() || is_standard_attribute(key))
      throw fail(fmt::format("attribute name '{}' is reserved", key));

  try {
    Imf::Header header(image.width, image.height);
    header.compression() = Imf::ZIP_COMPRESSION;
    for (const auto& c : image.channels) header.channels().insert(c.name, Imf::Channel(Imf::FLOAT));
    for (const auto& [key, value] : image.attributes) header.insert(key, Imf::StringAttribute(value));

    Imf::FrameBuffer fb;
    for (const auto& c : image.channels)
      fb.insert(c.name, Imf::Slice::Make(Imf::FLOAT, c.data.data(), header.dataWindow(), sizeof(float),
                                         sizeof(float) * std::size_t(image.width)));
    microsim::write_file_atomically(path, [&](const std::filesystem::path& tmp) {
      Imf::OutputFile file(tmp.c_str(), header);
      file.setFrameBuffer(fb);
      file.writePixels(image.height);
    });  // the destructor flushes and closes before the rename
  } catch (const std::exception& e) {
    throw fail(e.what());
  }
}

namespace {

// An Imf::IStream over bytes in memory (the fuzz targets and read_exr_memory); reads past the end throw
// Iex::InputExc, as OpenEXR's own streams do.
class MemoryIStream final : public Imf::IStream {
public:
  MemoryIStream(std::span<const char> bytes, const std::string& name) : Imf::IStream(name.c_str()), bytes_(bytes) {}
  bool read(char c[], int n) override {
    if (n < 0 || pos_ > bytes_.size() || std::size_t(n) > bytes_.size() - pos_)
      throw IEX_NAMESPACE::InputExc("unexpected end of file");
    std::memcpy(c, bytes_.data() + pos_, std::size_t(n));
    pos_ += std::size_t(n);
    return pos_ < bytes_.size();
  }
  std::uint64_t tellg() override { return pos_; }
  void seekg(std::uint64_t pos) override { pos_ = pos; }

private:
  std::span<const char> bytes_;
  std::uint64_t pos_ = 0;
};

std::string format_bytes(double bytes) {
  if (bytes >= double(1 << 30)) return fmt::format("{:.1f} GiB", bytes / double(1 << 30));
  if (bytes >= double(1 << 20)) return fmt::format("{:.1f} MiB", bytes / double(1 << 20));
  return fmt::format("{:.0f} bytes", bytes);
}

std::string read_name(Imf::IStream& in, const char* what) {
  std::string name;
  for (char c = 0;; name += c) {
    in.read(&c, 1);
    if (c == '\0') return name;
    if (name.size() == 255) throw std::runtime_error(fmt::format("header: {} longer than 255 bytes", what));
  }
}

std::uint32_t le32(std::string_view b, std::size_t at) {
  return std::uint32_t(std::uint8_t(b[at])) | std::uint32_t(std::uint8_t(b[at + 1])) << 8 |
         std::uint32_t(std::uint8_t(b[at + 2])) << 16 | std::uint32_t(std::uint8_t(b[at + 3])) << 24;
}

// The value bytes of a fixed-size attribute type (OpenEXR's standard types), 0 for one of variable size.
std::size_t fixed_value_size(const std::string& type) {
  static const std::map<std::string, std::size_t, std::less<>> sizes = {
      {"box2i", 16}, {"box2f", 16}, {"chromaticities", 32}, {"compression", 1}, {"deepImageState", 1},
      {"double", 8}, {"envmap", 1}, {"float", 4}, {"int", 4}, {"keycode", 28}, {"lineOrder", 1},
      {"m33f", 36}, {"m33d", 72}, {"m44f", 64}, {"m44d", 128}, {"rational", 8}, {"tiledesc", 9},
      {"timecode", 8}, {"v2i", 8}, {"v2f", 8}, {"v2d", 16}, {"v3i", 12}, {"v3f", 12}, {"v3d", 24}};
  const auto it = sizes.find(type);
  return it == sizes.end() ? 0 : it->second;
}

// Whether OpenEXR's reader of `type` consumes exactly the value's declared bytes. It reads fixed-size
// types, channel lists, string vectors and previews by their content, not by the declared size: a
// value whose content disagrees with its size would make the rest of the header parse from the wrong
// offset (and OpenEXR allocate whatever size it then reads).
bool value_fills_its_size(const std::string& type, std::string_view v) {
  if (const std::size_t fixed = fixed_value_size(type)) return v.size() == fixed;
  if (type == "floatvector") return v.size() % 4 == 0;
  if (type == "preview")
    return v.size() >= 8 && double(le32(v, 0)) * le32(v, 4) * 4 == double(v.size() - 8);
  if (type == "stringvector") {
    std::size_t at = 0;
    while (at < v.size()) {
      if (v.size() - at < 4 || le32(v, at) > v.size() - at - 4) return false;
      at += 4 + le32(v, at);
    }
    return true;
  }
  if (type == "chlist") {  // (name \0, pixel type, pLinear, 3 reserved, x sampling, y sampling)..., \0
    std::size_t at = 0;
    for (;;) {
      const std::size_t nul = v.find('\0', at);
      if (nul == std::string_view::npos || nul - at > 255) return false;
      if (nul == at) return nul + 1 == v.size();
      at = nul + 1 + 16;
      if (at > v.size()) return false;
    }
  }
  if (type == "idmanifest") return false;  // compressed: not needed, not supported
  return true;                             // string, and unknown types (read as opaque bytes)
}

// Walks the header's attribute list (name, type, size, value), as OpenEXR will parse it: every value
// must fit in the file and fill its declared size exactly. Checked before OpenEXR reads the header,
// because OpenEXR allocates a declared size before reading it (a 100-byte file declaring a 2 GB string
// attribute allocates 2 GB) and trusts a value's content over its size.
void check_attributes(Imf::IStream& in, std::uint64_t file_bytes) {
  in.seekg(8);  // magic number and version field
  for (;;) {
    const std::string name = read_name(in, "an attribute name");
    if (name.empty()) return;
    const std::string type = read_name(in, "an attribute type name");
    char size_bytes[4];
    in.read(size_bytes, 4);
    const std::uint32_t size = le32(std::string_view(size_bytes, 4), 0);
    const std::uint64_t at = in.tellg();
    if (size > 0x7fffffffu || at > file_bytes || size > file_bytes - at)
      throw std::runtime_error(fmt::format("header: attribute {} declares {} bytes, beyond the end of the file",
                                           microsim::reader::quote_excerpt(name), size));
    std::string value(size, '\0');
    in.read(value.data(), int(size));
    if (!value_fills_its_size(type, value))
      throw std::runtime_error(fmt::format("header: attribute {} of type {} has a malformed {}-byte value",
                                           microsim::reader::quote_excerpt(name),
                                           microsim::reader::quote_excerpt(type), size));
  }
}

// Scan lines per chunk of each compression (OpenEXR file layout); 0 for an unknown one.
int lines_per_chunk(Imf::Compression c) {
  switch (c) {
    case Imf::NO_COMPRESSION: case Imf::RLE_COMPRESSION: case Imf::ZIPS_COMPRESSION: return 1;
    case Imf::ZIP_COMPRESSION: case Imf::PXR24_COMPRESSION: return 16;
    case Imf::PIZ_COMPRESSION: case Imf::B44_COMPRESSION: case Imf::B44A_COMPRESSION:
    case Imf::DWAA_COMPRESSION: return 32;
    case Imf::DWAB_COMPRESSION: return 256;
    default: return 0;
  }
}

// The largest ratio of pixel bytes to stored bytes a compression can reach, where one bounds it cheaply
// (none: 1; RLE: a 2-byte run codes at most 127 bytes; zlib, ZIP and PXR24: deflate's limit of 1032:1,
// PXR24 also stores a 4-byte float in 3); 0 when no cheap bound is known (PIZ, B44, DWA).
double max_compression_ratio(Imf::Compression c) {
  switch (c) {
    case Imf::NO_COMPRESSION: return 1;
    case Imf::RLE_COMPRESSION: return 64;
    case Imf::ZIPS_COMPRESSION: case Imf::ZIP_COMPRESSION: return 1032;
    case Imf::PXR24_COMPRESSION: return 1032 * 4.0 / 3.0;
    default: return 0;
  }
}

// The sizes the header claims, checked before anything is allocated for them: the decoded float data,
// and one tile or chunk of scan lines, against `max_decoded_bytes`, and what the file must then hold
// (its chunk offset table, and the pixel data where the compression bounds its ratio) against the
// file's size.
void check_claimed_size(const Imf::Header& header, int version, std::uint64_t file_bytes,
                        std::uint64_t max_decoded_bytes) {
  const Imath::Box2i dw = header.dataWindow();
  const double w = double(dw.max.x) - dw.min.x + 1, h = double(dw.max.y) - dw.min.y + 1;
  if (!(w > 0 && h > 0) || w > double(INT_MAX) || h > double(INT_MAX))
    throw std::runtime_error(fmt::format("bad data window {} x {}", w, h));
  double channels = 0, stored_pixel_bytes = 0;
  for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
    channels += 1;
    stored_pixel_bytes += it.channel().type == Imf::HALF ? 2 : 4;
  }
  const double decoded = w * h * channels * 4;  // exact below 2^53: doubles, so no overflow
  if (decoded > double(max_decoded_bytes))
    throw std::runtime_error(fmt::format(
        "the header claims {} x {} pixels x {} channel{} = {} of float data, over the limit of {} ({} bytes)", w, h,
        channels, channels == 1 ? "" : "s", format_bytes(decoded), format_bytes(double(max_decoded_bytes)),
        max_decoded_bytes));
  double chunks = 0;
  if (Imf::isTiled(version)) {
    const Imf::TileDescription& t = header.tileDescription();
    if (double(t.xSize) * t.ySize * channels * 4 > double(max_decoded_bytes))
      throw std::runtime_error(fmt::format("the header claims tiles of {} x {} pixels, over the limit of {}",
                                           t.xSize, t.ySize, format_bytes(double(max_decoded_bytes))));
    chunks = std::ceil(w / t.xSize) * std::ceil(h / t.ySize);  // level 0 alone: a lower bound
  } else if (const int lines = lines_per_chunk(header.compression()); lines > 0) {
    chunks = std::ceil(h / lines);
    // OpenEXR sizes its line buffer and its decompressor's buffers for a whole chunk of `lines` scan
    // lines, however few lines the image has: a one-line image of DWAB compression allocates 256 lines.
    if (w * lines * channels * 4 > double(max_decoded_bytes))
      throw std::runtime_error(fmt::format(
          "the header claims scan lines of {} pixels x {} channel{}, which its compression decodes {} lines at a "
          "time: {} of float data, over the limit of {}", w, channels, channels == 1 ? "" : "s", lines,
          format_bytes(w * lines * channels * 4), format_bytes(double(max_decoded_bytes))));
  }
  if (chunks * 8 > double(file_bytes))
    throw std::runtime_error(fmt::format("the header claims {} x {} pixels, whose {} chunk offsets alone need more "
                                         "than the file's {} bytes (truncated or damaged)", w, h, chunks, file_bytes));
  const double ratio = max_compression_ratio(header.compression());
  if (ratio > 0 && w * h * stored_pixel_bytes > ratio * double(file_bytes))
    throw std::runtime_error(fmt::format(
        "the header claims {} x {} pixels x {} channel{} ({}), more than its compression can store in the file's "
        "{} bytes (truncated or damaged)", w, h, channels, channels == 1 ? "" : "s",
        format_bytes(w * h * stored_pixel_bytes), file_bytes));
}

// Reads and checks the header at the start of `in`: magic number, a single-part image (scan lines or
// tiles; no deep data, no multi-part file), attribute sizes, claimed pixel sizes. Leaves `in` at 0.
void check_header(Imf::IStream& in, std::uint64_t file_bytes, std::uint64_t max_decoded_bytes) {
  char start[8];
  in.seekg(0);
  in.read(start, 8);
  if (!Imf::isImfMagic(start)) throw std::runtime_error("not an OpenEXR file (no magic number)");
  int version = 0;
  for (int i = 0; i < 4; ++i) version |= int(static_cast<unsigned char>(start[4 + i])) << (8 * i);
  if (Imf::getVersion(version) != 2 || !Imf::supportsFlags(Imf::getFlags(version)))
    throw std::runtime_error(fmt::format("unsupported OpenEXR version field {:#x}", unsigned(version)));
  if (Imf::isMultiPart(version) || Imf::isNonImage(version))
    throw std::runtime_error("multi-part and deep EXR files are not supported (one part of flat pixels is)");
  check_attributes(in, file_bytes);
  in.seekg(8);
  Imf::Header header;
  header.readFrom(in, version);
  header.sanityCheck(Imf::isTiled(version));
  check_claimed_size(header, version, file_bytes, max_decoded_bytes);
  in.seekg(0);
}

// Decodes every channel of a checked file as float, and its string attributes.
ExrImage decode(Imf::IStream& in) {
  Imf::InputFile file(in);
  const Imf::Header& header = file.header();
  const Imath::Box2i dw = header.dataWindow();
  ExrImage image;
  image.width = dw.max.x - dw.min.x + 1;
  image.height = dw.max.y - dw.min.y + 1;
  const std::size_t texels = std::size_t(image.width) * std::size_t(image.height);
  Imf::FrameBuffer fb;
  const Imf::ChannelList& list = header.channels();
  for (auto it = list.begin(); it != list.end(); ++it) {
    if (it.channel().xSampling != 1 || it.channel().ySampling != 1)
      throw std::runtime_error(fmt::format("channel '{}' is subsampled, which is not supported", it.name()));
  }
  for (auto it = list.begin(); it != list.end(); ++it) image.channels.push_back({it.name(), std::vector<float>(texels)});
  if (image.channels.empty()) throw std::runtime_error("no channels");
  for (auto& c : image.channels)
    fb.insert(c.name, Imf::Slice::Make(Imf::FLOAT, c.data.data(), dw, sizeof(float),
                                       sizeof(float) * std::size_t(image.width)));
  file.setFrameBuffer(fb);
  if (!file.isComplete()) throw std::runtime_error("file is incomplete (truncated)");
  file.readPixels(dw.min.y, dw.max.y);
  for (auto it = header.begin(); it != header.end(); ++it)
    if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(&it.attribute()))
      image.attributes[it.name()] = s->value();
  return image;
}

ExrImage read_checked(Imf::IStream& in, const std::string& name, std::uint64_t file_bytes,
                      std::uint64_t max_decoded_bytes) {
  try {
    check_header(in, file_bytes, max_decoded_bytes);
    return decode(in);
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception& e) {
    throw std::runtime_error(fmt::format("cannot read EXR '{}': {}", name, e.what()));
  }
}

}  // namespace

ExrImage read_exr(const std::filesystem::path& path, std::uint64_t max_decoded_bytes) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw std::runtime_error(fmt::format("cannot read EXR '{}': no such file", path.string()));
  const std::uint64_t file_bytes = std::filesystem::file_size(path, ec);
  if (ec) throw std::runtime_error(fmt::format("cannot read EXR '{}': {}", path.string(), ec.message()));
  std::unique_ptr<Imf::StdIFStream> in;
  try {
    in = std::make_unique<Imf::StdIFStream>(path.c_str());
  } catch (const std::exception& e) {
    throw std::runtime_error(fmt::format("cannot read EXR '{}': {}", path.string(), e.what()));
  }
  return read_checked(*in, path.string(), file_bytes, max_decoded_bytes);
}

ExrImage read_exr_memory(std::span<const char> bytes, const std::string& name, std::uint64_t max_decoded_bytes) {
  MemoryIStream in(bytes, name);
  return read_checked(in, name, bytes.size(), max_decoded_bytes);
}

}  // namespace microgeom
