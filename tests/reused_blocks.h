// How the model tests check that a layer never reads memory it has not written: a pass runs in fresh memory (block
// cache off), then once more to fill the cache with the sizes it needs, then again with every reused block filled
// with NaN bits (core/block_pool.h). The last result must be bit for bit the first.
#pragma once

#include <cstdint>
#include <cstring>
#include <functional>

#include "core/block_pool.h"
#include "core/tensor.h"

namespace egopd::testing_memory {

struct ReusedBlocksRun {
  Tensor fresh, reused;
  uint64_t hits = 0;        // blocks the poisoned pass took from the cache
  int64_t differing = 0;    // elements whose bits differ between the two results
};

inline ReusedBlocksRun run_in_fresh_and_poisoned_blocks(const std::function<Tensor()>& pass) {
  ReusedBlocksRun r;
  const size_t saved = block_cache_limit();
  set_block_cache_limit(0);
  r.fresh = pass();
  set_block_cache_limit(size_t(256) << 20);
  (void)pass();
  set_block_cache_poison(true);
  const uint64_t hits = block_cache_stats().hits;
  r.reused = pass();
  set_block_cache_poison(false);
  r.hits = block_cache_stats().hits - hits;
  set_block_cache_limit(0);  // empty
  set_block_cache_limit(saved);
  if (r.fresh.shape() != r.reused.shape()) return r.differing = -1, r;
  for (int64_t i = 0; i < r.fresh.numel(); ++i)
    r.differing += std::memcmp(r.fresh.data() + i, r.reused.data() + i, sizeof(float)) != 0;
  return r;
}

}  // namespace egopd::testing_memory
