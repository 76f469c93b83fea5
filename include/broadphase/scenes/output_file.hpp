/// \file lab/output_file.hpp
/// Output files that are whole or absent: the bytes go to a temporary name
/// in the same directory, which is renamed over the target only once every
/// byte is written and synced. An interrupted or failed write leaves the
/// previous file (or none) and never a truncated one under the real name.
#pragma once

#include <filesystem>
#include <memory>
#include <ostream>
#include <string>
#include <string_view>

namespace broadphase {

/// One output file being written. Write through stream(), then commit().
/// Destroying an uncommitted OutputFile removes its temporary file. Errors
/// throw std::runtime_error naming the path and the system's reason
/// (strerror), e.g. "out/x.csv: cannot create: Not a directory".
///
/// A target that exists and is not a regular file (/dev/stdout, /dev/full,
/// a FIFO) is written in place: renaming over a device would replace it.
/// Not thread-safe; one OutputFile per thread.
class OutputFile {
 public:
  /// Opens the temporary file `<dir>/.<stem>.partial-<pid>-<k><ext>`.
  explicit OutputFile(std::filesystem::path path);
  ~OutputFile();
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  /// The stream to write to; its write errors are reported by commit().
  std::ostream& stream();
  /// Flushes, syncs and renames the file into place. Throws on any error
  /// (the temporary file is then removed).
  void commit();
  /// The final path.
  const std::filesystem::path& path() const { return path_; }

 private:
  struct Impl;
  std::filesystem::path path_;
  std::unique_ptr<Impl> impl_;
};

/// Writes `content` to `path` whole or not at all (see OutputFile).
void write_file_atomically(const std::filesystem::path& path, std::string_view content);

/// A file that another program writes (a plotting script): it writes to
/// temp(), and commit() renames that into place. Until then the temporary
/// name is removed by the destructor and by remove_partial_outputs().
class PendingFile {
 public:
  /// Picks `<dir>/.<stem>.partial-<pid>-<k><ext>` (the extension is kept:
  /// a picture writer picks the format from it). Nothing is created.
  explicit PendingFile(std::filesystem::path path);
  ~PendingFile();
  PendingFile(const PendingFile&) = delete;
  PendingFile& operator=(const PendingFile&) = delete;

  const std::filesystem::path& temp() const { return temp_; }
  const std::filesystem::path& path() const { return path_; }
  /// Renames temp() over path(). Throws std::runtime_error with the reason
  /// (also when temp() was never written).
  void commit();

 private:
  std::filesystem::path path_, temp_;
  int slot_ = -1;
};

/// Checks that files can be made in `dir` by making and removing a probe
/// file, before a long run writes there. Throws std::runtime_error naming
/// the directory and the reason ("Not a directory", "Read-only file system",
/// "No space left on device", ...).
void check_writable_directory(const std::filesystem::path& dir);

/// Removes the temporary files of every OutputFile still open. Only
/// async-signal-safe calls: meant for a SIGINT or SIGTERM handler.
void remove_partial_outputs() noexcept;

}  // namespace broadphase
