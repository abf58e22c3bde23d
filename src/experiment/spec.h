// experiment: the experiment spec: what a scene needs, in the user's terms. A TOML file (toml++)
// or the same structure in JSON (nlohmann-json):
//
//   name = "renderer-ggx-gold"          # optional; default: the file's stem
//   seed = 1                            # optional; every measurement derives its streams from it
//
//   [[material]]
//   name = "gold"
//   ndf = "ggx"                         # ggx | beckmann
//   alphas = [0.1, 0.25, [0.2, 0.4]]    # isotropic values or (alpha_x, alpha_y) pairs; or alpha = 0.3 / [ax, ay]
//   type = "conductor"                  # mirror | conductor | dielectric
//   eta = [0.143, 0.374, 1.442]         # conductor: per channel (or one number); dielectric: one number
//   k = [3.983, 2.385, 1.603]           # conductor only, as many as eta
//
//   [[quantity]]
//   kind = "albedo"                     # albedo | vndf | scattering | validation | masking
//   material = "gold"
//   orders = "single"                   # albedo, scattering: single | all
//   target_relative_error = 1e-3        # albedo's target: the relative standard error of every E(mu) and E_avg
//   # vndf, scattering: target_tv (a total-variation distance the histogram must resolve);
//   # validation: detect_tv (the smallest TV deviation to detect), power (0.9), significance (0.01), sampler
//   # vndf, scattering, validation: theta = [0, 30, 60] (degrees) or theta_range = {from, to, count}; phi = [0]
//   # masking: what = ["g1", "g2", "conditional"], target_standard_error (absolute), theta/phi as above,
//   #   light_theta = [..], light_phi = [0] (g2's lights), bins = 10 (conditional), resolution = 256 (a built surface)
//   surface = "auto"                    # auto | an assembly name (microgeom) | a heightmap .exr path
//
// Every key is checked: an unknown key, a wrong type, a target <= 0, a material no quantity can find, a
// direction below the horizon where the quantity does not allow it are SpecErrors naming the key path
// (quantity[2].target_tv) and the line. Library code: parses and checks, never prints.
#pragma once

#include "core/ndf_kind.h"
#include "core/output_paths.h"
#include "microfacet/bsdf_convention.h"
#include "microfacet/material.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace microsim::experiment {

// A bad spec: bad input (core/errors.h: std::invalid_argument -> exit 2). The message is
// "FILE:LINE: KEY: what is wrong"; key() and line() give the parts (line 0: not known).
class SpecError : public std::invalid_argument {
public:
  SpecError(std::string source, int line, std::string key, const std::string& problem);
  const std::string& key() const { return key_; }
  int line() const { return line_; }

private:
  std::string key_;
  int line_ = 0;
};

// A quantity's measurement kind, by the name the spec gives it. What a kind is (its keys, model, plan, rounds,
// values, files, report) is its registry entry's alone (measurement_registry.cpp kKinds, found by this name):
// a kind is added there and in its own file, never here. The built-in kinds' names are spelled out below.
struct QuantityKind {
  std::string_view name = "albedo";  // the registry's (static storage)
  bool operator==(const QuantityKind&) const = default;
  static const QuantityKind albedo, vndf, scattering, validation, masking;
};
inline constexpr QuantityKind QuantityKind::albedo{"albedo"}, QuantityKind::vndf{"vndf"},
    QuantityKind::scattering{"scattering"}, QuantityKind::validation{"validation"}, QuantityKind::masking{"masking"};
inline std::string to_string(QuantityKind kind) { return std::string(kind.name); }

struct SpecQuantity;
// Whether a validation's dump holds a BSDF's samples (pdf bsdf) or weights (weight columns): its BSDF is then its
// material's facet (a mirror, a conductor or a dielectric).
bool dump_has_bsdf(const SpecQuantity& quantity);

enum class Orders { single, all };  // order 1 only, or every order of multiple scattering
std::string to_string(Orders orders);  // "single", "all"

struct SpecMaterial {
  std::string name;
  NdfKind ndf = NdfKind::ggx;
  std::vector<std::pair<double, double>> alphas;  // (alpha_x, alpha_y), in the spec's order
  Material facet = Material::mirror();
  int line = 0;
  bool isotropic() const;
};

struct Direction {
  double theta_deg = 0, phi_deg = 0;
};

// The surface a quantity is measured on: the Smith model's own (auto), an assembly built by microgeom, or a
// heightmap file.
struct SurfaceChoice {
  enum class Kind { automatic, assembly, heightmap } kind = Kind::automatic;
  std::string name;  // the assembly's name or the heightmap's path
};

// What a masking quantity measures (its `what`): the scalar Smith masking G1(v); the masking-shadowing
// G2(v, l) for each of its lights; the conditional masking G1(v | bin) in bins of <v, m> and of height (an
// explicit surface's: Smith's model has none of its own).
struct MaskingWhat {
  bool g1 = false, g2 = false, conditional = false;
};
std::string to_string(const MaskingWhat& what);  // "g1, g2, conditional" (those asked for)

// A masking quantity's surface built per alpha when the spec names an assembly or asks for conditional
// masking on the automatic surface: N x N, N a power of two in [kMinMaskingResolution, kMaxMaskingResolution].
inline constexpr int kDefaultMaskingResolution = 256;
inline constexpr int kMinMaskingResolution = 16;
inline constexpr int kMaxMaskingResolution = 4096;
inline constexpr int kMaxMaskingRealisations = 64;

struct SpecQuantity {
  QuantityKind kind = QuantityKind::albedo;
  std::string key;       // "quantity[K]" (K from 0), as errors and the plan name it
  int line = 0;
  std::string material;  // a SpecMaterial's name
  Orders orders = Orders::single;
  double target = 0;     // albedo: relative SE; vndf, scattering: TV to resolve; validation: TV to detect (0:
                         // a dump without detect_tv, its rows fix it); masking: the absolute SE of every G1, G2
                         // and conditional G1(v | bin)
  std::vector<Direction> directions;  // vndf, scattering, validation, masking (the views)
  SurfaceChoice surface;
  int mus = 16;          // albedo: Gauss-Legendre nodes in mu
  bool inside = false;   // albedo of a dielectric from inside
  int rows = 31;         // vndf, validation: rows of the validator's binnings
  std::string sampler;   // validation: a zoo sampler's name (drawn), or
  std::string dump;      // validation: a sample file (.npy or text; a relative path is the spec folder's)
  std::string dump_pdf = "vndf";  // validation of a dump: the density it claims (FilePdf; bsdf: the material's BSDF)
  bool above_horizon = false;     // validation of a dump of reflections: only those above the horizon kept
  bool lost_as_zero_weight = false;  // validation of a dump: the sampler's lost samples kept as rows of weight 0
  std::string dump_columns = "x,y,z";  // validation of a dump: what its columns hold (SampleColumns::parse)
  std::string dump_frame = "z-up";     // validation of a dump: the frame of its rows (z-up or y-up)
  std::uint64_t dump_dropped = 0;      // validation of a dump above the horizon: the samples its renderer dropped
  BsdfConvention convention;           // validation of a dump of a BSDF: its weights' transport mode and masking form
  double power = 0.9, significance = 0.01;  // validation
  MaskingWhat masking;                      // masking: what is measured
  std::vector<Direction> lights;            // masking with g2: the lights, every one with every view
  int bins = 10;                            // masking, conditional: bins of <v, m> and of height
  int resolution = kDefaultMaskingResolution;  // masking on a surface built per alpha
  int realisations = 1;  // masking on a built surface: independent surfaces (seeds), each measured to the target
  // A kind's own settings beyond the members above (its reader fills them; the spec's digest holds them): a new
  // kind's keys need no member here.
  nlohmann::json settings = nlohmann::json::object();
};

struct ExperimentSpec {
  std::string name;
  std::string source;    // the file it was read from (messages, results)
  std::uint64_t seed = 1;
  std::vector<SpecMaterial> materials;
  std::vector<SpecQuantity> quantities;

  const SpecMaterial& material(std::string_view name) const;  // throws std::out_of_range
};

// Parses TOML text; `source` names it in messages (a path). Throws SpecError.
ExperimentSpec parse_spec_toml(std::string_view text, const std::string& source);
// Parses JSON text of the same structure (lines located in the text). Throws SpecError.
ExperimentSpec parse_spec_json(std::string_view text, const std::string& source);
// Reads a file: .json as JSON, anything else as TOML. Throws SpecError (an unreadable file is line 0).
ExperimentSpec load_spec(const std::filesystem::path& path);

// The files a spec reads, named by key ("SPEC", "quantity[2].dump", "quantity[0].plugin", a heightmap surface):
// what a command writing files must never overwrite.
std::vector<PathOption> spec_input_files(const ExperimentSpec& spec);

// A canonical description of the spec's content (not its source or formatting): equal for equal specs,
// whether written in TOML or JSON. results.json records its hash; a run refuses a directory holding another
// spec's results.
std::string canonical_spec(const ExperimentSpec& spec);
std::string spec_digest(const ExperimentSpec& spec);  // 16 hex digits of a 64-bit hash of canonical_spec

}  // namespace microsim::experiment
