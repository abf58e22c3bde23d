// measure: the BSDF plugin loader (bsdf_plugin_loader.h).
#include "measure/bsdf_plugin_loader.h"

#include "microsim/bsdf_plugin.h"

#include <dlfcn.h>
#include <fmt/core.h>

namespace microsim {

PluginLoadError::PluginLoadError(const std::string& path, const std::string& problem)
    : std::invalid_argument(fmt::format("'{}': {}", path, problem)), path_(path), problem_(problem) {}

struct BsdfPlugin::Loaded {
  void* library = nullptr;
  const microsim_bsdf_plugin* api = nullptr;
  void* self = nullptr;
  ~Loaded() {
    if (self) api->destroy(self);
    if (library) dlclose(library);
  }
  // The flags of ABI 2; a version-1 plugin's struct ends before them.
  int flags() const { return api->abi_version >= 2 ? api->flags : 0; }
};

namespace {

// The checks of the plugin's table before anything of it is called but its entry point.
void check_plugin_api(const std::string& path, const microsim_bsdf_plugin* api) {
  if (!api || api->abi_version < 1 || api->abi_version > MICROSIM_BSDF_PLUGIN_ABI)
    throw PluginLoadError(path, fmt::format("not of ABI version 1 to {}", MICROSIM_BSDF_PLUGIN_ABI));
  if (api->channels < 1 || api->channels > MICROSIM_BSDF_MAX_CHANNELS)
    throw PluginLoadError(path, fmt::format("{} channels", api->channels));
  if (!api->create || !api->destroy || !api->sample || !api->eval || (!api->pdf && api->abi_version < 2))
    throw PluginLoadError(path, "a function pointer is NULL");
  constexpr int known = MICROSIM_BSDF_STOCHASTIC_EVAL | MICROSIM_BSDF_NDF_SAMPLING;
  if (api->abi_version >= 2 && (api->flags & ~known) != 0)
    throw PluginLoadError(path, fmt::format("flags {:#x}: bits this microsim does not know (it knows {:#x})", api->flags, known));
}

void plugin_raw(const Vec3<double>& v, double out[3]) { out[0] = v.x(), out[1] = v.y(), out[2] = v.z(); }

}  // namespace

BsdfPlugin::BsdfPlugin(const std::string& path, const std::string& params) : loaded_(std::make_unique<Loaded>()) {
  loaded_->library = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!loaded_->library) {
    const char* why = dlerror();
    throw PluginLoadError(path, why ? why : "cannot be loaded");
  }
  const auto entry =
      reinterpret_cast<microsim_bsdf_plugin_entry_fn>(dlsym(loaded_->library, "microsim_bsdf_plugin_entry"));
  if (!entry) throw PluginLoadError(path, "no microsim_bsdf_plugin_entry");
  loaded_->api = entry();
  check_plugin_api(path, loaded_->api);
  loaded_->self = loaded_->api->create(params.c_str());
  if (!loaded_->self) throw PluginLoadError(path, fmt::format("create(\"{}\") refused the parameters", params));
}

BsdfPlugin::~BsdfPlugin() = default;

std::string BsdfPlugin::name() const { return loaded_->api->name ? loaded_->api->name : "plugin"; }
int BsdfPlugin::channels() const { return loaded_->api->channels; }
bool BsdfPlugin::stochastic_eval() const { return (loaded_->flags() & MICROSIM_BSDF_STOCHASTIC_EVAL) != 0; }
bool BsdfPlugin::has_pdf() const { return loaded_->api->pdf != nullptr; }
SampledNormals BsdfPlugin::sampled_normals() const {
  return (loaded_->flags() & MICROSIM_BSDF_NDF_SAMPLING) ? SampledNormals::ndf : SampledNormals::visible;
}

BsdfUnderTest BsdfPlugin::under_test() const {
  const Loaded& p = *loaded_;
  BsdfUnderTest b;
  b.name = name();
  b.channels = p.api->channels;
  b.convention = {p.api->transport == 1 ? TransportMode::importance : TransportMode::radiance,
                  p.api->masking == 1 ? MaskingForm::separable : MaskingForm::height_correlated, sampled_normals()};
  b.stochastic_eval = stochastic_eval();
  const std::size_t c = std::size_t(b.channels);
  b.sample = [&p, c](std::span<const Vec3<double>> wi, std::span<const double> u, std::span<Vec3<double>> wo,
                     std::span<double> pdf, std::span<double> weight, std::span<unsigned char> kept) {
    for (std::size_t i = 0; i < wi.size(); ++i) {
      double in[3], out[3] = {0, 0, 0};
      plugin_raw(wi[i], in);
      kept[i] = (unsigned char)(p.api->sample(p.self, in, &u[3 * i], out, &pdf[i], &weight[c * i]) != 0);
      wo[i] = Vec3<double>(out[0], out[1], out[2]);
    }
  };
  b.eval = [&p, c](std::span<const Vec3<double>> wi, std::span<const Vec3<double>> wo, std::span<double> value) {
    for (std::size_t i = 0; i < wi.size(); ++i) {
      double in[3], out[3];
      plugin_raw(wi[i], in), plugin_raw(wo[i], out);
      p.api->eval(p.self, in, out, &value[c * i]);
    }
  };
  if (!p.api->pdf) return b;  // no closed-form density
  b.pdf = [&p](std::span<const Vec3<double>> wi, std::span<const Vec3<double>> wo, std::span<double> pdf) {
    for (std::size_t i = 0; i < wi.size(); ++i) {
      double in[3], out[3];
      plugin_raw(wi[i], in), plugin_raw(wo[i], out);
      pdf[i] = p.api->pdf(p.self, in, out);
    }
  };
  return b;
}

}  // namespace microsim
