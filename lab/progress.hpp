// A progress bar on stderr for long commands: what is running, how far it
// is, and the time left. Redrawn in place on a terminal; on a pipe or a log
// file it prints a plain line now and then instead, so logs stay readable.
#pragma once

#include <chrono>
#include <cstdio>
#include <string>

namespace broadphase::app {

/// Reports the progress of one long command. Not thread-safe: call it from
/// the thread doing the work.
class ProgressBar {
 public:
  /// Draws on `out` (stderr by default). `quiet` draws nothing at all.
  explicit ProgressBar(std::FILE* out = stderr, bool quiet = false);
  ~ProgressBar();
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;

  /// Says what runs now, the fraction done in [0, 1] and the seconds left
  /// (negative: estimated from the time elapsed and the fraction). Cheap to
  /// call often: it redraws at most ten times a second on a terminal and
  /// every `plain_interval` seconds otherwise.
  void update(const std::string& what, double fraction, double seconds_left = -1);
  /// Prints a line of its own (a warning, a skipped step) without garbling
  /// the bar.
  void message(const std::string& line);
  /// Erases the bar so that other code can print to the same stream; the
  /// next update draws it again.
  void clear();
  /// Clears the bar and prints the total time (once; the destructor calls it).
  void finish(const std::string& what = "done");

  /// Seconds since the bar was made, on the lab's clock (budget.hpp: the
  /// wall clock unless a time scale is set).
  double elapsed() const;
  /// Seconds between two plain lines when the output is not a terminal.
  void set_plain_interval(double seconds) { plain_interval_ = seconds; }
  bool is_terminal() const { return tty_; }

  /// "1h02m", "3m05s", "42s".
  static std::string format_seconds(double s);

 private:
  void draw(const std::string& what, double fraction, double seconds_left);
  void clear_line();

  std::FILE* out_;
  bool quiet_;
  bool tty_;
  bool finished_ = false;
  bool drawn_ = false;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
  double plain_interval_ = 10;
  std::string last_what_;
  std::size_t last_width_ = 0;
};

}  // namespace broadphase::app
