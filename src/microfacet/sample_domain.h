// microfacet: what a sampler's samples are (a microfacet normal or a reflected direction), apart from the
// sampler registry (samplers.h) so that a binning (stats/binning.h) can name it without the zoo.
#pragma once

namespace microsim {

enum class SampleDomain {
  microfacet_normal,    // samples are microfacet normals m; analytic reference: D_v(wi, m)
  reflected_direction,  // samples are reflected directions wo; reference: the pdf over wo
};

}  // namespace microsim
