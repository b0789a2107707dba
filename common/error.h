#pragma once
/// Error channels (see docs/architecture): InputError for bad input and
/// configuration (caught in app/ and turned into one line), LP_CHECK for bugs.
#include <sstream>
#include <stdexcept>
#include <string>

namespace lp {

/// Bad input or configuration: the message names the file and the problem.
class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& what) : std::runtime_error(what) {}
  InputError(const std::string& file, const std::string& problem)
      : std::runtime_error(file + ": " + problem) {}
};

/// Work stopped on request (a Cancel button, a closing window): not an error.
class Cancelled : public std::runtime_error {
 public:
  Cancelled() : std::runtime_error("cancelled") {}
};

[[noreturn]] void CheckFailed(const char* expr, const char* file, int line, const std::string& msg);

}  // namespace lp

/// Internal invariant: on failure prints the expression, location and message, then throws
/// std::logic_error (a bug, not bad input).
#define LP_CHECK(cond, msg)                                                   \
  do {                                                                        \
    if (!(cond)) {                                                            \
      std::ostringstream lp_check_os_;                                        \
      lp_check_os_ << msg;                                                    \
      ::lp::CheckFailed(#cond, __FILE__, __LINE__, lp_check_os_.str());       \
    }                                                                         \
  } while (0)
