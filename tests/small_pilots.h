// tests: the experiment planner with small pilots (a test's plan in a second, not the default's minutes).
#pragma once

#include "experiment/plan.h"

namespace microsim::test {

inline experiment::ExperimentPlan plan_with_small_pilots(const experiment::ExperimentSpec& spec) {
  experiment::PlanOptions o;
  o.pilot_paths = 1024;
  o.pilot_rays = 1 << 14;
  o.cap_pilot_paths = 1 << 13;
  return experiment::plan_experiment(spec, o);
}

}  // namespace microsim::test
