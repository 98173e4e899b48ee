#pragma once
// Shared by the test executables: the message of the error that a piece of code throws, for
// tests of refused input (the message must name the file, line, key and the accepted range).

#include <string>
#include <utility>

namespace demfem::test {

/// @brief Runs `f()` and returns the what() of the `Error` it throws, or `none` when it
/// returns normally. Only `Error` (and what derives from it) is caught: an exception of
/// another type propagates and fails the test case, so the type is part of the check.
template <class Error, class F>
std::string error_of(F&& f, const std::string& none = "(no error)") {
  try {
    std::forward<F>(f)();
  } catch (const Error& e) {
    return e.what();
  }
  return none;
}

}  // namespace demfem::test
