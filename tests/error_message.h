// A test helper: the message of the exception a call throws.
#pragma once

#include <exception>
#include <functional>
#include <string>

namespace microsim::test {

// What `f` throws (its what()), or "(no exception)".
inline std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no exception)";
}

}  // namespace microsim::test
