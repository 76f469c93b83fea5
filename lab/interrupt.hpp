// Interruption of long runs: what SIGINT (Ctrl-C) and SIGTERM do, and the
// child processes (the plotting scripts) run so that their end is seen.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

namespace broadphase::app {

/// Installs the SIGINT and SIGTERM handlers. On either signal the handler
/// removes the outputs still being written (broadphase::OutputFile,
/// PendingFile), stops the running child and waits for it (so that it
/// writes nothing afterwards), prints the note of set_interrupt_note(), and
/// ends the process by the same signal (status 130 or 143 in a shell).
/// Only async-signal-safe calls run in the handler.
void install_interrupt_handlers();

/// A line the handler prints on stderr, e.g. how to resume; empty: none.
/// Not thread-safe (call from the main thread, outside the handler).
void set_interrupt_note(const std::string& note);

/// How a child process ended.
struct ProcessStatus {
  bool started = false;  ///< false when it could not be started at all
  int exit_code = -1;    ///< its exit status when it exited, else -1
  int signal = 0;        ///< the signal that ended it, else 0
  bool ok() const { return started && exit_code == 0; }
  /// "exit status 3", "killed by signal 2 (Interrupt)", "could not start: ...".
  std::string describe() const;
  std::string error;  ///< why it could not start
};

/// Runs `argv` (argv[0] looked up on PATH) and waits for it; stdout and
/// stderr are the caller's, or /dev/null with `quiet`. The child is known
/// to the signal handler while it runs.
ProcessStatus run_process(const std::vector<std::string>& argv, bool quiet = false);

/// Thrown when a child process was ended by SIGINT or SIGTERM: the run was
/// interrupted, not failed (a plot script killed by Ctrl-C is not a
/// missing matplotlib).
class ChildInterrupted : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace broadphase::app
