// An error in what the user asked for, thrown by the lab (a bad --algos, a
// bad drawing option) and the CLI alike.
#pragma once

#include <stdexcept>

namespace broadphase::app {

/// An error in what the user asked for: printed without a stack of causes,
/// exit status 2.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace broadphase::app
