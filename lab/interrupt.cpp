#include "interrupt.hpp"

#include <fcntl.h>
#include <pthread.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <broadphase/scenes/output_file.hpp>
#include <cerrno>
#include <cstring>
#include <ctime>

extern char** environ;

namespace broadphase::app {

namespace {

std::atomic<pid_t> g_child{0};
// The note is written by the main thread before any long step and read by
// the handler: a fixed buffer, published by an atomic length.
char g_note[1024];
std::atomic<std::size_t> g_note_size{0};

void write_all(const char* p, std::size_t n) {
  while (n > 0) {
    const ssize_t w = ::write(2, p, n);
    if (w <= 0) return;
    p += w;
    n -= static_cast<std::size_t>(w);
  }
}

// Stops the child: the same signal, up to two seconds to end, then SIGKILL.
void stop_child(int sig) {
  const pid_t child = g_child.load();
  if (child <= 0) return;
  ::kill(child, sig);
  for (int i = 0; i < 200; ++i) {
    if (::waitpid(child, nullptr, WNOHANG) != 0) return;
    const timespec ten_ms{0, 10'000'000};
    ::nanosleep(&ten_ms, nullptr);
  }
  ::kill(child, SIGKILL);
  ::waitpid(child, nullptr, 0);
}

extern "C" void on_interrupt(int sig) {
  const int saved = errno;
  stop_child(sig);
  remove_partial_outputs();
  const char* what = sig == SIGINT ? "\nbroadphase: interrupted\n" : "\nbroadphase: terminated\n";
  write_all(what, std::strlen(what));
  const std::size_t n = g_note_size.load();
  if (n > 0) write_all(g_note, n);
  errno = saved;
  // End by the signal itself, so that a calling shell or script sees it.
  ::signal(sig, SIG_DFL);
  ::raise(sig);
}

}  // namespace

void install_interrupt_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_interrupt;
  sigemptyset(&sa.sa_mask);
  sigaddset(&sa.sa_mask, SIGINT);
  sigaddset(&sa.sa_mask, SIGTERM);
  for (const int sig : {SIGINT, SIGTERM}) {
    struct sigaction old {};
    // A signal ignored by the caller (nohup, a background job) stays ignored.
    if (::sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;
    ::sigaction(sig, &sa, nullptr);
  }
}

void set_interrupt_note(const std::string& note) {
  g_note_size.store(0);
  std::string text = note.empty() || note.back() == '\n' ? note : note + '\n';
  if (text.size() > sizeof g_note) text.resize(sizeof g_note);
  std::memcpy(g_note, text.data(), text.size());
  g_note_size.store(text.size());
}

std::string ProcessStatus::describe() const {
  if (!started) return "could not start: " + error;
  if (signal != 0)
    return "killed by signal " + std::to_string(signal) + " (" + strsignal(signal) + ")";
  return "exit status " + std::to_string(exit_code);
}

ProcessStatus run_process(const std::vector<std::string>& argv, bool quiet) {
  ProcessStatus st;
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (quiet) {
    posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
  }
  // The child starts with the default dispositions, not our handler.
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t defaults;
  sigemptyset(&defaults);
  sigaddset(&defaults, SIGINT);
  sigaddset(&defaults, SIGTERM);
  posix_spawnattr_setsigdefault(&attr, &defaults);
  // Block the signals while the child's pid is published, so the handler
  // never misses a child that is already running; the child gets the mask
  // from before.
  sigset_t old;
  pthread_sigmask(SIG_BLOCK, &defaults, &old);
  posix_spawnattr_setsigmask(&attr, &old);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETSIGMASK);
  pid_t pid = 0;
  const int err = posix_spawnp(&pid, args[0], &actions, &attr, args.data(), environ);
  if (err == 0) g_child.store(pid);
  pthread_sigmask(SIG_SETMASK, &old, nullptr);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  if (err != 0) {
    st.error = std::strerror(err);
    return st;
  }
  st.started = true;
  int status = 0;
  pid_t w;
  do {
    w = ::waitpid(pid, &status, 0);
  } while (w < 0 && errno == EINTR);
  g_child.store(0);
  if (w < 0) {
    st.exit_code = -1;
    return st;
  }
  if (WIFEXITED(status)) st.exit_code = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) st.signal = WTERMSIG(status);
  return st;
}

}  // namespace broadphase::app
