// core: the CPU time of the process, a cost measure that other load on the machine does not inflate.
#pragma once

namespace microsim {

// CPU seconds (user and system, every thread) the process has used so far (CLOCK_PROCESS_CPUTIME_ID).
double process_cpu_seconds();

}  // namespace microsim
