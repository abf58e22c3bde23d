// measure: a renderer's BSDF loaded in process from a shared library through the C interface of
// include/microsim/bsdf_plugin.h (dlopen; ABI 1 or 2), as the battery's BSDF under test (bsdf_battery.h):
// what `microsim check-bsdf --plugin` and an experiment's bsdf quantity run.
#pragma once

#include "measure/bsdf_battery.h"

#include <memory>
#include <stdexcept>
#include <string>

namespace microsim {

// A plugin that cannot be loaded: the library does not load (dlerror's text), has no entry point, is of another
// ABI version, has a NULL function or too many channels, or its create() refuses the parameters. Bad input
// (std::invalid_argument: exit 2). path(): the library as given; problem(): what is wrong.
class PluginLoadError : public std::invalid_argument {
public:
  PluginLoadError(const std::string& path, const std::string& problem);
  const std::string& path() const { return path_; }
  const std::string& problem() const { return problem_; }

private:
  std::string path_, problem_;
};

// The loaded library and one BSDF it created (create(params)); both released in reverse order on destruction.
class BsdfPlugin {
public:
  // `params`: the key=value pairs create() receives, space-separated. Throws PluginLoadError.
  BsdfPlugin(const std::string& path, const std::string& params);
  ~BsdfPlugin();
  BsdfPlugin(const BsdfPlugin&) = delete;
  BsdfPlugin& operator=(const BsdfPlugin&) = delete;

  std::string name() const;  // the plugin's own name, or "plugin"
  int channels() const;
  bool stochastic_eval() const;  // ABI 2's flag: eval() an unbiased noisy estimate
  bool has_pdf() const;          // a closed-form pdf() (ABI 2 may leave it NULL)
  SampledNormals sampled_normals() const;  // ABI 2's flag: the normals sample() draws (D(m) cos or visible)
  // The BSDF under test, each row one call from the calling thread; it refers to this plugin, which must outlive it.
  BsdfUnderTest under_test() const;

private:
  struct Loaded;
  std::unique_ptr<Loaded> loaded_;
};

}  // namespace microsim
