// Whole-or-nothing outputs: AtomicDir replaces a folder as a whole or leaves it untouched; AtomicFileWriter reports
// a full disk naming the file and leaves no temporary file; the interrupt flag turns into Interrupted.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/atomic_file.h"
#include "core/interrupt.h"

namespace egopd {
namespace {
namespace fs = std::filesystem;

class AtomicOutputs : public ::testing::Test {
 protected:
  fs::path root;
  void SetUp() override {
    root = fs::temp_directory_path() / ("egopd_atomic_test_" + std::to_string(::getpid()));
    fs::remove_all(root);
    fs::create_directories(root);
  }
  void TearDown() override { fs::remove_all(root); }
  static void put(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }
  static std::string read(const fs::path& p) {
    std::ifstream in(p);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
  int entries() const { return int(std::distance(fs::directory_iterator(root), fs::directory_iterator())); }
};

TEST_F(AtomicOutputs, CommitCreatesTheFolder) {
  {
    AtomicDir d((root / "out").string(), "a.txt");
    EXPECT_FALSE(fs::exists(root / "out"));
    put(fs::path(d.path()) / "a.txt", "new");
    d.commit();
  }
  EXPECT_EQ(read(root / "out" / "a.txt"), "new");
  EXPECT_EQ(entries(), 1);  // no temporary folder left
}

TEST_F(AtomicOutputs, CommitReplacesAnEarlierFolderAsAWhole) {
  fs::create_directories(root / "out");
  put(root / "out" / "heatmap_009.png", "old run, more frames");
  put(root / "out" / "a.txt", "old");
  {
    AtomicDir d((root / "out/").string(), "a.txt");  // a trailing separator names the same folder
    put(fs::path(d.path()) / "a.txt", "new");
    d.commit();
  }
  EXPECT_EQ(read(root / "out" / "a.txt"), "new");
  EXPECT_FALSE(fs::exists(root / "out" / "heatmap_009.png"));
  EXPECT_EQ(entries(), 1);
}

TEST_F(AtomicOutputs, UncommittedFolderIsRemovedAndTheOldOneKept) {
  fs::create_directories(root / "out");
  put(root / "out" / "a.txt", "old");
  try {
    AtomicDir d((root / "out").string(), "a.txt");
    put(fs::path(d.path()) / "a.txt", "half");
    throw Error("stage failed");
  } catch (const Error&) {
  }
  EXPECT_EQ(read(root / "out" / "a.txt"), "old");
  EXPECT_EQ(entries(), 1);
}

TEST_F(AtomicOutputs, StaleTemporariesOfAKilledRunAreFound) {
  fs::create_directories(root / ".clip.tmp-123-0" / "x");
  fs::create_directories(root / ".other.tmp-123-0");
  EXPECT_EQ(remove_stale_temporaries((root / "clip").string()), 1);
  EXPECT_FALSE(fs::exists(root / ".clip.tmp-123-0"));
  EXPECT_TRUE(fs::exists(root / ".other.tmp-123-0"));
}

// Temporaries of a cache entry left by a killed process go once nothing in them has changed for the idle time; a
// live writer's (a file in it changed lately), other entries' and the entry itself stay.
TEST_F(AtomicOutputs, AbandonedTemporariesGoLiveOnesStay) {
  const auto age = [](const fs::path& p, int seconds) {
    fs::last_write_time(p, fs::file_time_type::clock::now() - std::chrono::seconds(seconds));
  };
  fs::create_directories(root / "model.tmp-41" / "unet");
  put(root / "model.tmp-41" / "unet" / "w.safetensors", "old");
  age(root / "model.tmp-41" / "unet" / "w.safetensors", 7200);
  age(root / "model.tmp-41" / "unet", 7200);
  age(root / "model.tmp-41", 7200);
  fs::create_directories(root / "model.tmp-42" / "unet");  // a live writer: its folders old, one file fresh
  put(root / "model.tmp-42" / "unet" / "w.safetensors", "being written");
  age(root / "model.tmp-42" / "unet", 7200);
  age(root / "model.tmp-42", 7200);
  put(root / "w.safetensors.tmp.43", "old");
  age(root / "w.safetensors.tmp.43", 7200);
  put(root / "other.tmp-44", "old");
  age(root / "other.tmp-44", 7200);
  put(root / ".model.tmp-45-0", "old");  // AtomicDir's, killed outright
  age(root / ".model.tmp-45-0", 7200);
  put(root / ".model.tmp-46-0", "fresh");
  fs::create_directories(root / "model");
  age(root / "model", 7200);
  EXPECT_EQ(remove_abandoned_temporaries((root / "model").string(), 3600), 2);
  EXPECT_EQ(remove_abandoned_temporaries((root / "w.safetensors").string(), 3600), 1);
  EXPECT_FALSE(fs::exists(root / "model.tmp-41"));
  EXPECT_FALSE(fs::exists(root / ".model.tmp-45-0"));
  EXPECT_TRUE(fs::exists(root / ".model.tmp-46-0"));
  EXPECT_TRUE(fs::exists(root / "model.tmp-42" / "unet" / "w.safetensors"));
  EXPECT_FALSE(fs::exists(root / "w.safetensors.tmp.43"));
  EXPECT_TRUE(fs::exists(root / "other.tmp-44"));
  EXPECT_TRUE(fs::exists(root / "model"));
}

TEST_F(AtomicOutputs, AFolderThatIsNotAnEarlierOutputIsNeverReplaced) {
  fs::create_directories(root / "out");
  put(root / "out" / "thesis.tex", "years of work");
  try {
    AtomicDir d((root / "out").string(), "summary.json");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("is not an earlier output of this command (no summary.json)"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(read(root / "out" / "thesis.tex"), "years of work");
  EXPECT_EQ(entries(), 1);
  fs::remove(root / "out" / "thesis.tex");
  EXPECT_NO_THROW(AtomicDir((root / "out").string(), "summary.json"));  // an empty folder may be used
}

TEST_F(AtomicOutputs, TargetThatIsAFileIsAnError) {
  put(root / "out", "a file");
  try {
    AtomicDir d((root / "out").string(), "a.txt");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("is not a folder"), std::string::npos) << e.what();
  }
  EXPECT_EQ(read(root / "out"), "a file");
}

// A full disk, emulated with a file-size limit (write() then fails with EFBIG instead of raising SIGXFSZ).
TEST_F(AtomicOutputs, FullDiskNamesTheFileAndKeepsTheOldOne) {
  put(root / "taxels.csv", "old complete file\n");
  struct rlimit old {};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old), 0);
  void (*old_handler)(int) = ::signal(SIGXFSZ, SIG_IGN);
  struct rlimit small = old;
  small.rlim_cur = 4096;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &small), 0);
  std::string message;
  try {
    write_file_atomic((root / "taxels.csv").string(), std::string(100000, 'x'));
  } catch (const Error& e) {
    message = e.what();
  }
  ::setrlimit(RLIMIT_FSIZE, &old);
  ::signal(SIGXFSZ, old_handler);
  EXPECT_NE(message.find((root / "taxels.csv").string() + ": write failed"), std::string::npos) << message;
  EXPECT_EQ(message.find('\n'), std::string::npos);
  EXPECT_EQ(read(root / "taxels.csv"), "old complete file\n");
  EXPECT_EQ(entries(), 1);  // the temporary file is gone
}

TEST(Interrupt, PendingSignalBecomesInterruptedWithItsExitCode) {
  clear_interrupt();
  EXPECT_NO_THROW(throw_if_interrupted("after step 1 of 4"));
  request_interrupt(SIGTERM);
  try {
    throw_if_interrupted("after step 2 of 4");
    FAIL() << "no Interrupted";
  } catch (const Interrupted& e) {
    EXPECT_EQ(e.exit_code(), 143);
    EXPECT_NE(std::string(e.what()).find("SIGTERM after step 2 of 4"), std::string::npos) << e.what();
  }
  clear_interrupt();
  install_interrupt_handlers();
  ::raise(SIGINT);  // recorded by the handler, not fatal
  EXPECT_EQ(pending_interrupt(), SIGINT);
  EXPECT_THROW(throw_if_interrupted(), Interrupted);
  clear_interrupt();
}

}  // namespace
}  // namespace egopd
