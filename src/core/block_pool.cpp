#include "core/block_pool.h"

#include <atomic>
#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>
#include <string>

#include "core/error.h"
#include "core/memory.h"

namespace egopd {
namespace {

#if EGOPD_ADDRESS_SANITIZER
constexpr size_t kDefaultLimit = 0;
#else
constexpr size_t kDefaultLimit = size_t(1) << 30;
#endif

class BlockPool {
 public:
  // A cached block of at least `bytes` (its real size in `bytes`), or null.
  void* take(size_t& bytes) {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = free_.lower_bound(bytes);  // the smallest cached block that holds the request
    if (it == free_.end() || it->first - bytes > it->first / 8) {
      ++misses_;
      return nullptr;
    }
    void* p = it->second.p;
    bytes = it->first;
    cached_ -= bytes;
    free_.erase(it);
    ++hits_;
    return p;
  }

  void give(void* p, size_t bytes) {
    std::lock_guard<std::mutex> lock(mu_);
    if (bytes > limit_) {  // too large to keep, or caching is off
      std::free(p);
      return;
    }
    free_.emplace(bytes, Cached{p, ++clock_});
    cached_ += bytes;
    shrink_to(limit_);
  }

  void set_limit(size_t bytes) {
    std::lock_guard<std::mutex> lock(mu_);
    limit_ = bytes;
    shrink_to(limit_);
  }
  void empty() {
    std::lock_guard<std::mutex> lock(mu_);
    shrink_to(0);
  }
  size_t limit() {
    std::lock_guard<std::mutex> lock(mu_);
    return limit_;
  }
  BlockCacheStats stats() {
    std::lock_guard<std::mutex> lock(mu_);
    return {cached_, free_.size(), hits_, misses_};
  }

 private:
  struct Cached {
    void* p;
    uint64_t released;  // clock_ at release: the oldest goes first
  };

  // Gives back the longest-cached blocks until at most `bytes` stay (a few dozen entries: a scan is enough).
  void shrink_to(size_t bytes) {
    while (cached_ > bytes) {
      auto oldest = free_.begin();
      for (auto it = free_.begin(); it != free_.end(); ++it)
        if (it->second.released < oldest->second.released) oldest = it;
      std::free(oldest->second.p);
      cached_ -= oldest->first;
      free_.erase(oldest);
    }
  }

  std::mutex mu_;
  std::multimap<size_t, Cached> free_;
  size_t cached_ = 0, limit_ = kDefaultLimit;
  uint64_t clock_ = 0, hits_ = 0, misses_ = 0;
};

// Never destroyed: tensors held by static objects may be freed after any destructor of this file would have run.
BlockPool& pool() {
  static BlockPool* p = new BlockPool;
  return *p;
}

std::atomic<bool> poison_reused{false};

size_t rounded(size_t bytes) { return bytes < 64 ? 64 : (bytes + 63) / 64 * 64; }

}  // namespace

void* pooled_alloc(size_t& bytes) {
  bytes = rounded(bytes);
  if (bytes < kPooledBlockMinBytes) return aligned_alloc_checked(bytes);
  if (void* p = pool().take(bytes)) {
    if (poison_reused.load(std::memory_order_relaxed)) std::memset(p, 0xff, bytes);  // 0xffffffff: a NaN
    return p;
  }
  return aligned_alloc_checked(bytes);
}

void pooled_free(void* p, size_t bytes) {
  if (!p) return;
  if (bytes < kPooledBlockMinBytes)
    std::free(p);
  else
    pool().give(p, bytes);
}

void set_block_cache_limit(size_t bytes) { pool().set_limit(bytes); }
size_t block_cache_limit() { return pool().limit(); }
void empty_block_cache() { pool().empty(); }
size_t default_block_cache_limit() { return kDefaultLimit; }

size_t block_cache_limit_from_env() {
  const char* e = std::getenv("EGOPD_BLOCK_CACHE_MB");
  if (!e || !*e) return kDefaultLimit;
  char* end = nullptr;
  errno = 0;
  const long long mb = std::strtoll(e, &end, 10);
  if (*end != '\0' || errno != 0 || mb < 0 || mb > kMaxBlockCacheMb || !std::isdigit(static_cast<unsigned char>(*e)))
    throw Error(std::string("EGOPD_BLOCK_CACHE_MB='") + e + "' is not a size in MiB (0.." +
                std::to_string(kMaxBlockCacheMb) + ")");
  return size_t(mb) << 20;
}
void set_block_cache_poison(bool on) { poison_reused.store(on); }
BlockCacheStats block_cache_stats() { return pool().stats(); }

}  // namespace egopd
