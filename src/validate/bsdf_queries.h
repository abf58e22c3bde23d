// validate: the query set a renderer fills in for `microsim check-eval` (`microsim bsdf-queries`): pairs
// (wi, wo) stratified over the sphere, plus the edge cases renderers get wrong.
#pragma once

#include "core/math.h"
#include "microfacet/ggx.h"
#include "microfacet/material.h"

#include <cstdint>
#include <optional>
#include <vector>

namespace microsim {

struct BsdfQuery {
  Vec3<double> wi, wo;
};

// The views: theta 0, 30, 60, 80 and 89.9 deg at phi 0 and 45 deg (an anisotropic lobe turned), and for a
// dielectric the same from inside (180 deg - theta). Per view: `per_view` wo jittered in equal-area cells of
// the sphere (a dielectric) or the upper hemisphere (CounterRng(seed, view)); the mirror direction, wo = wi,
// wo = -wi, wo grazing at 89.9 deg in 8 azimuths, a dielectric's refraction through the mean surface; with
// `ggx`, per_view / 4 more wo reflected (and for a dielectric refracted) about normals drawn from its visible
// normals (Heitz 2018), where a narrow lobe has its values. std::invalid_argument for per_view < 2.
std::vector<BsdfQuery> bsdf_queries(const Material& bsdf, int per_view, std::uint64_t seed,
                                    const std::optional<GGX<double>>& ggx);

}  // namespace microsim
