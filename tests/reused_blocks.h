// The block cache (core/block_pool.h) in tests: a limit for one scope, and how the model tests check that a layer
// never reads memory it has not written: a pass runs in fresh memory (block cache off), then once more to fill the
// cache with the sizes it needs, then again with every reused block filled with NaN bits. The last result must be
// bit for bit the first.
#pragma once

#include <cstdint>
#include <cstring>
#include <functional>

#include "core/block_pool.h"
#include "core/tensor.h"

namespace egopd::testing_memory {

// The cache emptied and limited to `bytes` for the scope (set() changes it), then emptied and given its limit back.
class ScopedBlockCacheLimit {
 public:
  explicit ScopedBlockCacheLimit(size_t bytes) : saved_(block_cache_limit()) {
    set(0);
    set(bytes);
  }
  ~ScopedBlockCacheLimit() {
    set(0);
    set(saved_);
  }
  ScopedBlockCacheLimit(const ScopedBlockCacheLimit&) = delete;
  ScopedBlockCacheLimit& operator=(const ScopedBlockCacheLimit&) = delete;
  void set(size_t bytes) { set_block_cache_limit(bytes); }

 private:
  size_t saved_;
};

struct ReusedBlocksRun {
  Tensor fresh, reused;
  uint64_t hits = 0;        // blocks the poisoned pass took from the cache
  int64_t differing = 0;    // elements whose bits differ between the two results
};

inline ReusedBlocksRun run_in_fresh_and_poisoned_blocks(const std::function<Tensor()>& pass) {
  ReusedBlocksRun r;
  {
    ScopedBlockCacheLimit limit(0);
    r.fresh = pass();
    limit.set(size_t(256) << 20);
    (void)pass();
    set_block_cache_poison(true);
    const uint64_t hits = block_cache_stats().hits;
    r.reused = pass();
    set_block_cache_poison(false);
    r.hits = block_cache_stats().hits - hits;
  }
  if (r.fresh.shape() != r.reused.shape()) {
    r.differing = -1;
    return r;
  }
  for (int64_t i = 0; i < r.fresh.numel(); ++i)
    r.differing += std::memcmp(r.fresh.data() + i, r.reused.data() + i, sizeof(float)) != 0;
  return r;
}

}  // namespace egopd::testing_memory
