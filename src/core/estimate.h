// core: a Monte Carlo estimate: a value and its standard error (of the mean). Degenerate inputs give 0,
// never NaN.
#pragma once

namespace microsim {

struct Estimate {
  double value = 0;
  double standard_error = 0;
};

}  // namespace microsim
