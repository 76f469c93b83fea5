#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <broadphase/scenes/output_file.hpp>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <streambuf>
#include <vector>

namespace broadphase {

namespace {

namespace fs = std::filesystem;

// The temporary names in use, for a signal handler to remove: fixed slots of
// heap strings, claimed and released with atomics (no lock, no allocation in
// the handler).
constexpr int kSlots = 64;
std::array<std::atomic<char*>, kSlots> g_partial{};

int claim_slot(const fs::path& p) {
  char* copy = strdup(p.c_str());
  if (copy == nullptr) throw std::bad_alloc();
  for (int i = 0; i < kSlots; ++i) {
    char* expected = nullptr;
    if (g_partial[i].compare_exchange_strong(expected, copy)) return i;
  }
  std::free(copy);  // more than kSlots at once: still written safely, just not swept
  return -1;
}

void release_slot(int slot) {
  if (slot < 0) return;
  std::free(g_partial[slot].exchange(nullptr));
}

std::atomic<unsigned> g_counter{0};

fs::path temporary_for(const fs::path& path) {
  const fs::path dir = path.parent_path();
  std::string name = "." + path.stem().string() + ".partial-" + std::to_string(::getpid()) + "-" +
                     std::to_string(g_counter++) + path.extension().string();
  return dir / name;
}

std::runtime_error failure(const fs::path& path, const char* what, int err) {
  return std::runtime_error(path.string() + ": " + what + ": " + std::strerror(err));
}

// A stream buffer over a file descriptor that keeps the first write error's
// errno, so that the message can name it (an ofstream forgets why).
class FdBuf : public std::streambuf {
 public:
  explicit FdBuf(int fd) : fd_(fd), buf_(1 << 16) { setp(buf_.data(), buf_.data() + buf_.size()); }
  int error() const { return error_; }
  bool drain() {
    const char* p = pbase();
    std::size_t left = static_cast<std::size_t>(pptr() - pbase());
    while (left > 0 && error_ == 0) {
      const ssize_t w = ::write(fd_, p, left);
      if (w < 0) {
        if (errno == EINTR) continue;
        error_ = errno;
        break;
      }
      p += w;
      left -= static_cast<std::size_t>(w);
    }
    setp(buf_.data(), buf_.data() + buf_.size());
    return error_ == 0;
  }

 protected:
  int_type overflow(int_type c) override {
    if (!drain()) return traits_type::eof();
    if (!traits_type::eq_int_type(c, traits_type::eof())) {
      *pptr() = traits_type::to_char_type(c);
      pbump(1);
    }
    return traits_type::not_eof(c);
  }
  int sync() override { return drain() ? 0 : -1; }
  std::streamsize xsputn(const char* s, std::streamsize n) override {
    if (n > epptr() - pptr()) {
      if (!drain()) return 0;
      if (n > static_cast<std::streamsize>(buf_.size())) {
        // Large writes go straight through.
        const char* p = s;
        std::size_t left = static_cast<std::size_t>(n);
        while (left > 0) {
          const ssize_t w = ::write(fd_, p, left);
          if (w < 0) {
            if (errno == EINTR) continue;
            error_ = errno;
            return static_cast<std::streamsize>(p - s);
          }
          p += w;
          left -= static_cast<std::size_t>(w);
        }
        return n;
      }
    }
    std::memcpy(pptr(), s, static_cast<std::size_t>(n));
    pbump(static_cast<int>(n));
    return n;
  }

 private:
  int fd_;
  std::vector<char> buf_;
  int error_ = 0;
};

}  // namespace

struct OutputFile::Impl {
  fs::path temp;  // empty when writing in place
  int fd = -1;
  int slot = -1;
  FdBuf buf;
  std::ostream out;
  bool done = false;
  explicit Impl(int f) : fd(f), buf(f), out(&buf) {}
};

OutputFile::OutputFile(fs::path path) : path_(std::move(path)) {
  struct stat st {};
  if (::stat(path_.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {
    if (S_ISDIR(st.st_mode)) throw failure(path_, "cannot write", EISDIR);
    const int fd = ::open(path_.c_str(), O_WRONLY | O_CLOEXEC);
    if (fd < 0) throw failure(path_, "cannot write", errno);
    impl_ = std::make_unique<Impl>(fd);
    return;
  }
  const fs::path temp = temporary_for(path_);
  const int slot = claim_slot(temp);
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) {
    const int err = errno;
    release_slot(slot);
    throw failure(path_, "cannot create", err);
  }
  impl_ = std::make_unique<Impl>(fd);
  impl_->temp = temp;
  impl_->slot = slot;
}

OutputFile::~OutputFile() {
  if (!impl_ || impl_->done) return;
  if (impl_->fd >= 0) ::close(impl_->fd);
  if (!impl_->temp.empty()) ::unlink(impl_->temp.c_str());
  release_slot(impl_->slot);
}

std::ostream& OutputFile::stream() { return impl_->out; }

void OutputFile::commit() {
  Impl& i = *impl_;
  if (i.done) return;
  i.out.flush();
  int err = i.buf.error();
  const char* what = "write failed";
  if (err == 0 && !i.temp.empty() && ::fsync(i.fd) != 0) err = errno;
  if (::close(i.fd) != 0 && err == 0) err = errno;
  i.fd = -1;
  if (err == 0 && !i.temp.empty() && ::rename(i.temp.c_str(), path_.c_str()) != 0) {
    err = errno;
    what = "cannot rename into place";
  }
  if (err != 0) {
    if (!i.temp.empty()) ::unlink(i.temp.c_str());
    release_slot(i.slot);
    i.done = true;
    throw failure(path_, what, err);
  }
  release_slot(i.slot);
  i.done = true;
}

void write_file_atomically(const fs::path& path, std::string_view content) {
  OutputFile f(path);
  f.stream().write(content.data(), static_cast<std::streamsize>(content.size()));
  f.commit();
}

PendingFile::PendingFile(fs::path path)
    : path_(std::move(path)), temp_(temporary_for(path_)), slot_(claim_slot(temp_)) {}

PendingFile::~PendingFile() {
  if (slot_ == -2) return;
  ::unlink(temp_.c_str());
  release_slot(slot_);
}

void PendingFile::commit() {
  if (::rename(temp_.c_str(), path_.c_str()) != 0) throw failure(path_, "cannot write", errno);
  release_slot(slot_);
  slot_ = -2;  // committed: nothing to remove
}

void check_writable_directory(const fs::path& dir) {
  const fs::path d = dir.empty() ? fs::path(".") : dir;
  const fs::path probe = d / (".write-probe-" + std::to_string(::getpid()));
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw failure(d, "cannot write files here", errno);
  int err = 0;
  if (::write(fd, "x", 1) != 1) err = errno != 0 ? errno : EIO;
  if (::close(fd) != 0 && err == 0) err = errno;
  ::unlink(probe.c_str());
  if (err != 0) throw failure(d, "cannot write files here", err);
}

void remove_partial_outputs() noexcept {
  for (auto& slot : g_partial) {
    const char* p = slot.load();
    if (p != nullptr) ::unlink(p);
  }
}

}  // namespace broadphase
