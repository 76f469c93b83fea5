#include "progress.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>

#include "budget.hpp"

namespace broadphase::app {

ProgressBar::ProgressBar(std::FILE* out, bool quiet)
    : out_(out),
      quiet_(quiet),
      tty_(isatty(fileno(out)) != 0),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_ - std::chrono::hours(1)) {}

ProgressBar::~ProgressBar() {
  if (drawn_ && !finished_) clear_line();
}

double ProgressBar::elapsed() const { return lab_seconds_since(start_); }

std::string ProgressBar::format_seconds(double s) {
  if (!(s >= 0) || !std::isfinite(s)) return "?";
  const long t = std::lround(s);
  char buf[32];
  if (t >= 3600)
    std::snprintf(buf, sizeof buf, "%ldh%02ldm", t / 3600, (t / 60) % 60);
  else if (t >= 60)
    std::snprintf(buf, sizeof buf, "%ldm%02lds", t / 60, t % 60);
  else
    std::snprintf(buf, sizeof buf, "%lds", t);
  return buf;
}

void ProgressBar::update(const std::string& what, double fraction, double seconds_left) {
  if (quiet_ || finished_) return;
  const auto now = std::chrono::steady_clock::now();
  const double since = std::chrono::duration<double>(now - last_draw_).count();
  // A terminal is redrawn often; a log gets a line per interval, and a line
  // whenever the phase (the text before the first ':') changes.
  const bool new_phase =
      what.substr(0, what.find(':')) != last_what_.substr(0, last_what_.find(':'));
  if (since < (tty_ ? 0.1 : plain_interval_) && !new_phase) return;
  last_draw_ = now;
  last_what_ = what;
  fraction = std::clamp(fraction, 0.0, 1.0);
  if (seconds_left < 0) {
    const double e = elapsed();
    seconds_left = fraction > 0.01 ? e * (1 - fraction) / fraction : -1;
  }
  draw(what, fraction, seconds_left);
}

void ProgressBar::draw(const std::string& what, double fraction, double seconds_left) {
  const int pct = static_cast<int>(fraction * 100);
  const std::string left = seconds_left >= 0 ? format_seconds(seconds_left) : "?";
  if (!tty_) {
    std::fprintf(out_, "[%3d%%] %s (elapsed %s, about %s left)\n", pct, what.c_str(),
                 format_seconds(elapsed()).c_str(), left.c_str());
    std::fflush(out_);
    return;
  }
  constexpr int kBar = 24;
  const int full = static_cast<int>(fraction * kBar);
  std::string line = "\r[";
  line.append(static_cast<std::size_t>(full), '#');
  line.append(static_cast<std::size_t>(kBar - full), '.');
  char buf[64];
  std::snprintf(buf, sizeof buf, "] %3d%% %s left  ", pct, left.c_str());
  line += buf;
  std::string text = what;
  constexpr std::size_t kMaxText = 70;
  if (text.size() > kMaxText) text = text.substr(0, kMaxText - 3) + "...";
  line += text;
  const std::size_t width = line.size();
  if (width < last_width_) line.append(last_width_ - width, ' ');
  last_width_ = width;
  std::fputs(line.c_str(), out_);
  std::fflush(out_);
  drawn_ = true;
}

void ProgressBar::clear_line() {
  if (!tty_ || !drawn_) return;
  std::fprintf(out_, "\r%*s\r", static_cast<int>(last_width_), "");
  last_width_ = 0;
  drawn_ = false;
}

void ProgressBar::clear() {
  if (quiet_) return;
  clear_line();
  last_draw_ = std::chrono::steady_clock::now() - std::chrono::hours(1);
}

void ProgressBar::message(const std::string& line) {
  if (quiet_) return;
  clear_line();
  std::fprintf(out_, "%s\n", line.c_str());
  std::fflush(out_);
  // Redraw at the next update rather than waiting out the interval.
  last_draw_ = std::chrono::steady_clock::now() - std::chrono::hours(1);
}

void ProgressBar::finish(const std::string& what) {
  if (quiet_ || finished_) return;
  clear_line();
  finished_ = true;
  std::fprintf(out_, "%s in %s\n", what.c_str(), format_seconds(elapsed()).c_str());
  std::fflush(out_);
}

}  // namespace broadphase::app
