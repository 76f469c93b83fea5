// Output files whole or absent, write errors with their reason, quoted
// excerpts of bad tokens, and the version macros.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <broadphase/scenes/excerpt.hpp>
#include <broadphase/scenes/output_file.hpp>
#include <broadphase/version.hpp>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>

namespace {

namespace fs = std::filesystem;
using broadphase::OutputFile;

class OutputFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("broadphase-output-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::size_t files() const {
    return static_cast<std::size_t>(std::distance(fs::directory_iterator(dir_), {}));
  }
  static std::string read(const fs::path& p) {
    std::ifstream in(p);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }
  fs::path dir_;
};

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no error)";
}

TEST_F(OutputFileTest, CommitWritesTheWholeFileAndNoTemporary) {
  const std::string big(3 << 20, 'x');  // larger than the stream's buffer
  {
    OutputFile f(dir_ / "a.csv");
    f.stream() << "head\n" << big;
    EXPECT_FALSE(fs::exists(dir_ / "a.csv")) << "visible before commit";
    f.commit();
  }
  EXPECT_EQ(read(dir_ / "a.csv"), "head\n" + big);
  EXPECT_EQ(files(), 1u);
}

TEST_F(OutputFileTest, WithoutCommitNothingIsLeftAndTheOldFileStays) {
  broadphase::write_file_atomically(dir_ / "a.csv", "old\n");
  {
    OutputFile f(dir_ / "a.csv");
    f.stream() << "half a new fi";
  }
  EXPECT_EQ(read(dir_ / "a.csv"), "old\n");
  EXPECT_EQ(files(), 1u);
}

TEST_F(OutputFileTest, RemovePartialOutputsRemovesTheTemporary) {
  OutputFile f(dir_ / "a.csv");
  f.stream() << "x";
  EXPECT_EQ(files(), 1u);
  broadphase::remove_partial_outputs();
  EXPECT_EQ(files(), 0u);
}

TEST_F(OutputFileTest, UnderARegularFileTheReasonIsNamed) {
  broadphase::write_file_atomically(dir_ / "regular", "");
  const std::string m = message_of([&] { OutputFile f(dir_ / "regular" / "x.csv"); });
  EXPECT_NE(m.find("regular/x.csv: cannot create: Not a directory"), std::string::npos) << m;
  const std::string p = message_of([&] { broadphase::check_writable_directory(dir_ / "regular"); });
  EXPECT_NE(p.find("cannot write files here: Not a directory"), std::string::npos) << p;
  EXPECT_EQ(message_of([&] { broadphase::check_writable_directory(dir_); }), "(no error)");
}

TEST_F(OutputFileTest, AFullDeviceIsWrittenInPlaceAndTheReasonNamed) {
  if (!fs::exists("/dev/full")) GTEST_SKIP() << "no /dev/full";
  const std::string m = message_of([] {
    OutputFile f("/dev/full");
    f.stream() << std::string(1 << 17, 'x');
    f.commit();
  });
  EXPECT_NE(m.find("/dev/full: write failed: No space left on device"), std::string::npos) << m;
  struct stat st {};
  ASSERT_EQ(::stat("/dev/full", &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode)) << "the device was replaced";
}

TEST_F(OutputFileTest, PendingFileRenamesWhatAnotherProgramWrote) {
  {
    broadphase::PendingFile p(dir_ / "pic.png");
    EXPECT_EQ(p.temp().extension(), ".png");
    EXPECT_EQ(p.temp().parent_path(), dir_);
    std::ofstream(p.temp()) << "PNG";
    p.commit();
  }
  EXPECT_EQ(read(dir_ / "pic.png"), "PNG");
  {
    broadphase::PendingFile p(dir_ / "other.png");
    std::ofstream(p.temp()) << "half";
  }
  EXPECT_EQ(files(), 1u);
}

TEST(Excerpt, ShortEscapedAndCut) {
  using broadphase::excerpt;
  EXPECT_EQ(excerpt("abc"), "'abc'");
  EXPECT_EQ(excerpt(std::string(10'000'000, '7')), "'" + std::string(40, '7') + "'...");
  EXPECT_EQ(excerpt("a\rb\x1b[1m"), "'a\\x0db\\x1b[1m'");
  EXPECT_EQ(excerpt("it's"), "'it\\x27s'");
  // A cut never splits a UTF-8 sequence: "é" is two bytes.
  EXPECT_EQ(excerpt("aé", 2), "'a'...");
}

TEST(Version, MacrosAgree) {
  const std::string expected = std::to_string(BROADPHASE_VERSION_MAJOR) + "." +
                               std::to_string(BROADPHASE_VERSION_MINOR) + "." +
                               std::to_string(BROADPHASE_VERSION_PATCH);
  EXPECT_EQ(expected, BROADPHASE_VERSION_STRING);
}

}  // namespace
