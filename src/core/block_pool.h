#pragma once
// A cache of freed large activation blocks. Memory fresh from the system costs a page fault per 4 KiB page on its
// first write (on some virtual machines about 10 us each: a tenth of an int8 U-Net evaluation), and a run allocates
// the same sizes again in every block and every evaluation. Freed blocks of at least kPooledBlockMinBytes are kept
// (up to a byte limit, the oldest given back first) and handed out again for a request of the same size or up to
// 1/8 smaller.
#include <cstddef>
#include <cstdint>

namespace egopd {

constexpr size_t kPooledBlockMinBytes = size_t(1) << 20;

// Like aligned_alloc_checked (memory.h) for any size, large blocks from the cache; `bytes` becomes the block's real
// size (at least the request). Free with pooled_free(p, that size).
void* pooled_alloc(size_t& bytes);
void pooled_free(void* p, size_t bytes);

// The most bytes of freed blocks kept (default_block_cache_limit() until set). Lowering it gives back the oldest
// blocks at once.
void set_block_cache_limit(size_t bytes);
size_t block_cache_limit();
// Gives back every cached block at once; the limit stays (the C API, when its last model is freed).
void empty_block_cache();
// 1 GiB; 0 under AddressSanitizer, so that it still sees every use after free.
size_t default_block_cache_limit();

// The largest limit a user may ask for, in MiB (--block-cache-mb, EGOPD_BLOCK_CACHE_MB, the C API's block_cache_mb).
constexpr int64_t kMaxBlockCacheMb = int64_t(1) << 20;
// The limit of a run that names none: EGOPD_BLOCK_CACHE_MB (MiB; 0 keeps no blocks) when set, else the default. An
// Error naming the variable when it is not a whole number of 0..kMaxBlockCacheMb.
size_t block_cache_limit_from_env();

// On: every block handed out again is first filled with NaN bits, so a layer that reads memory it has not written
// shows it (tests; fresh pages read as zeros and would hide it). Off by default.
void set_block_cache_poison(bool on);

struct BlockCacheStats {
  size_t cached_bytes = 0, cached_blocks = 0;
  uint64_t hits = 0, misses = 0;  // requests of pooled size served from the cache / by the system
};
BlockCacheStats block_cache_stats();

}  // namespace egopd
