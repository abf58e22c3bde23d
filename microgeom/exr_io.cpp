#include "microgeom/exr_io.h"

#include "microgeom/atomic_file.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>

#include <fmt/core.h>

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
    write_file_atomically(path, [&](const std::filesystem::path& tmp) {
      Imf::OutputFile file(tmp.c_str(), header);
      file.setFrameBuffer(fb);
      file.writePixels(image.height);
    });  // the destructor flushes and closes before the rename
  } catch (const std::exception& e) {
    throw fail(e.what());
  }
}

ExrImage read_exr(const std::filesystem::path& path) {
  auto fail = [&](const std::string& why) {
    return std::runtime_error(fmt::format("cannot read EXR '{}': {}", path.string(), why));
  };
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw fail("no such file");
  try {
    Imf::InputFile file(path.c_str());
    const Imf::Header& header = file.header();
    const Imath::Box2i dw = header.dataWindow();
    ExrImage image;
    const long long w = (long long)dw.max.x - dw.min.x + 1, h = (long long)dw.max.y - dw.min.y + 1;
    if (w <= 0 || h <= 0 || w * h > (1LL << 31)) throw fail(fmt::format("bad data window {} x {}", w, h));
    image.width = int(w);
    image.height = int(h);

    Imf::FrameBuffer fb;
    const Imf::ChannelList& list = header.channels();
    for (auto it = list.begin(); it != list.end(); ++it) {
      if (it.channel().xSampling != 1 || it.channel().ySampling != 1)
        throw fail(fmt::format("channel '{}' is subsampled, which is not supported", it.name()));
      image.channels.push_back({it.name(), std::vector<float>(std::size_t(w) * std::size_t(h), 0.0f)});
    }
    if (image.channels.empty()) throw fail("no channels");
    for (auto& c : image.channels)
      fb.insert(c.name, Imf::Slice::Make(Imf::FLOAT, c.data.data(), dw, sizeof(float),
                                         sizeof(float) * std::size_t(w)));
    file.setFrameBuffer(fb);
    if (!file.isComplete()) throw fail("file is incomplete (truncated)");
    file.readPixels(dw.min.y, dw.max.y);

    for (auto it = header.begin(); it != header.end(); ++it)
      if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(&it.attribute()))
        image.attributes[it.name()] = s->value();
    return image;
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    if (what.rfind("cannot read EXR", 0) == 0) throw;
    throw fail(what);
  } catch (const std::exception& e) {
    throw fail(e.what());
  }
}

}  // namespace microgeom
