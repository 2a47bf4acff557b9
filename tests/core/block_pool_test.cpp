#include "core/block_pool.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>

#include "core/error.h"
#include "core/tensor.h"
#include "reused_blocks.h"

namespace egopd {
namespace {

constexpr size_t kMiB = size_t(1) << 20;

// Each test sets its own limit (the default is 0 under AddressSanitizer) and leaves an empty cache behind.
class BlockPoolTest : public ::testing::Test {
 protected:
  testing_memory::ScopedBlockCacheLimit limit_{64 * kMiB};
};

// pooled_alloc with a request of `bytes`; the block's real size in *real
void* alloc(size_t bytes, size_t* real = nullptr) {
  void* p = pooled_alloc(bytes);
  if (real) *real = bytes;
  return p;
}

TEST_F(BlockPoolTest, FreedLargeBlockIsHandedOutAgainForTheSameSize) {
  size_t size = 0;
  void* a = alloc(3 * kMiB, &size);
  EXPECT_EQ(size, 3 * kMiB);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(a) % 64, 0u);
  std::memset(a, 1, size);
  pooled_free(a, size);
  EXPECT_EQ(block_cache_stats().cached_bytes, 3 * kMiB);
  const uint64_t hits = block_cache_stats().hits;
  void* b = alloc(3 * kMiB - 100, &size);  // rounded up to 64 bytes, then served by the cached block
  EXPECT_EQ(b, a);
  EXPECT_EQ(size, 3 * kMiB);
  EXPECT_EQ(block_cache_stats().hits, hits + 1);
  EXPECT_EQ(block_cache_stats().cached_bytes, 0u);
  pooled_free(b, size);
}

TEST_F(BlockPoolTest, ReusesABlockOnlyUpToAnEighthLarger) {
  void* a = alloc(8 * kMiB);
  pooled_free(a, 8 * kMiB);
  size_t small_size = 0, close_size = 0;
  void* small = alloc(6 * kMiB, &small_size);  // 8 MiB would waste a quarter: a new block
  EXPECT_NE(small, a);
  EXPECT_EQ(small_size, 6 * kMiB);
  void* close = alloc(7 * kMiB + kMiB / 2, &close_size);  // within an eighth: the cached 8 MiB block
  EXPECT_EQ(close, a);
  EXPECT_EQ(close_size, 8 * kMiB);
  std::memset(close, 2, close_size);
  pooled_free(small, small_size);
  pooled_free(close, close_size);
  EXPECT_EQ(block_cache_stats().cached_bytes, 14 * kMiB);
  EXPECT_EQ(block_cache_stats().cached_blocks, 2u);
}

TEST_F(BlockPoolTest, LimitGivesBackTheOldestBlocksFirst) {
  set_block_cache_limit(10 * kMiB);
  void* a = alloc(4 * kMiB);
  void* b = alloc(4 * kMiB + 64);
  void* c = alloc(4 * kMiB + 128);
  pooled_free(a, 4 * kMiB);
  pooled_free(b, 4 * kMiB + 64);
  pooled_free(c, 4 * kMiB + 128);  // 12 MiB and more over a 10 MiB limit: a, the oldest, goes
  EXPECT_EQ(block_cache_stats().cached_blocks, 2u);
  EXPECT_EQ(block_cache_stats().cached_bytes, 8 * kMiB + 192);
  set_block_cache_limit(5 * kMiB);  // lowering the limit gives back at once: b goes, c stays
  EXPECT_EQ(block_cache_stats().cached_blocks, 1u);
  EXPECT_EQ(alloc(4 * kMiB + 128), c);
  pooled_free(c, 4 * kMiB + 128);
  set_block_cache_limit(0);
  EXPECT_EQ(block_cache_stats().cached_bytes, 0u);
  void* d = alloc(2 * kMiB);  // with a limit of 0 a freed block goes straight back to the system
  pooled_free(d, 2 * kMiB);
  EXPECT_EQ(block_cache_stats().cached_blocks, 0u);
}

TEST_F(BlockPoolTest, SmallBlocksAreNotCached) {
  size_t size = 0;
  void* p = alloc(kPooledBlockMinBytes - 64, &size);
  pooled_free(p, size);
  EXPECT_EQ(block_cache_stats().cached_blocks, 0u);
}

TEST_F(BlockPoolTest, TensorsShareTheCache) {
  const Shape shape{16, 320, 8, 8};  // 1.25 MiB of floats
  float* first = nullptr;
  {
    Tensor t(shape);
    first = t.data();
    t[0] = 1.0f;
  }
  EXPECT_EQ(block_cache_stats().cached_blocks, 1u);
  Tensor again(shape);
  EXPECT_EQ(again.data(), first);
}

// EGOPD_BLOCK_CACHE_MB: a whole number of MiB, 0 included; anything else is an error naming the variable.
TEST(BlockCacheEnv, WholeMiBOrAnError) {
  const char* const name = "EGOPD_BLOCK_CACHE_MB";
  const char* const before = std::getenv(name);
  const std::string saved = before ? before : "";
  unsetenv(name);
  EXPECT_EQ(block_cache_limit_from_env(), default_block_cache_limit());
  setenv(name, "", 1);
  EXPECT_EQ(block_cache_limit_from_env(), default_block_cache_limit());
  setenv(name, "12", 1);
  EXPECT_EQ(block_cache_limit_from_env(), size_t(12) << 20);
  setenv(name, "0", 1);
  EXPECT_EQ(block_cache_limit_from_env(), 0u);
  setenv(name, "1048576", 1);
  EXPECT_EQ(block_cache_limit_from_env(), size_t(1) << 40);
  for (const char* bad : {"1048577", "-1", "+5", " 5", "5 ", "5M", "0x10", "1e3", "99999999999999999999"}) {
    setenv(name, bad, 1);
    try {
      block_cache_limit_from_env();
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()),
                std::string("EGOPD_BLOCK_CACHE_MB='") + bad + "' is not a size in MiB (0..1048576)");
    }
  }
  if (before)
    setenv(name, saved.c_str(), 1);
  else
    unsetenv(name);
}

}  // namespace
}  // namespace egopd
