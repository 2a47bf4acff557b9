#include "core/tensor.h"

#include <algorithm>
#include <cstdlib>
#include <new>

#include "core/block_pool.h"
#include "core/error.h"
#include "core/kernels/elementwise.h"
#include "core/memory.h"

namespace egopd {

Shape::Shape(std::initializer_list<int64_t> dims) {
  EGOPD_CHECK(dims.size() <= size_t(kMaxDims), "tensor rank above 6");
  for (int64_t v : dims) d_[n_++] = v;
}

Shape::Shape(const std::vector<int64_t>& dims) {
  if (dims.size() > size_t(kMaxDims)) throw Error("tensor rank " + std::to_string(dims.size()) + " above 6");
  for (int64_t v : dims) d_[n_++] = v;
}

int64_t Shape::numel() const {
  int64_t n = 1;
  for (int i = 0; i < n_; ++i) n *= d_[i];
  return n;
}

bool Shape::operator==(const Shape& o) const {
  if (n_ != o.n_) return false;
  for (int i = 0; i < n_; ++i)
    if (d_[i] != o.d_[i]) return false;
  return true;
}

std::string shape_string(const std::vector<int64_t>& dims) {
  std::string s = "[";
  for (size_t i = 0; i < dims.size(); ++i) s.append(i ? "," : "").append(std::to_string(dims[i]));
  return s + "]";
}

std::string Shape::str() const { return shape_string(vec()); }

std::shared_ptr<float[]> alloc_floats(size_t n) {
  size_t bytes = n * sizeof(float);
  float* p = static_cast<float*>(pooled_alloc(bytes));
  return std::shared_ptr<float[]>(p, [bytes](float* q) { pooled_free(q, bytes); });
}

// Arena chunks live as long as their arena, which reuses them itself: they bypass the block cache, so that
// shrink_to_peak() gives the old chunks back to the system.
static std::shared_ptr<float[]> alloc_chunk(size_t n) {
  const size_t bytes = std::max<size_t>(64, (n * sizeof(float) + 63) / 64 * 64);
  return std::shared_ptr<float[]>(static_cast<float*>(aligned_alloc_checked(bytes)), [](float* q) { std::free(q); });
}

Tensor::Tensor(const Shape& shape) : shape_(shape) {
  for (int i = 0; i < shape.ndim(); ++i)
    if (shape[i] < 0) throw Error("negative tensor dimension in " + shape.str());
  owner_ = alloc_floats(size_t(shape.numel()));
  data_ = owner_.get();
}

Tensor Tensor::zeros(const Shape& shape) { return full(shape, 0.0f); }

Tensor Tensor::full(const Shape& shape, float v) {
  Tensor t(shape);
  std::fill(t.data_, t.data_ + t.numel(), v);
  return t;
}

Tensor Tensor::from(const Shape& shape, const std::vector<float>& values) {
  EGOPD_CHECK(int64_t(values.size()) == shape.numel(), "value count does not match shape " + shape.str());
  Tensor t(shape);
  std::copy(values.begin(), values.end(), t.data_);
  return t;
}

Tensor Tensor::view(const Shape& shape, float* data) {
  Tensor t;
  t.shape_ = shape;
  t.data_ = data;
  return t;
}

Tensor Tensor::reshaped(const Shape& shape) const {
  EGOPD_CHECK(shape.numel() == numel(), "reshape " + shape_.str() + " -> " + shape.str());
  Tensor t = *this;
  t.shape_ = shape;
  return t;
}

Tensor Tensor::clone() const {
  Tensor t(shape_);
  copy_floats(t.data_, data_, numel());  // threaded for activation-sized tensors
  return t;
}

// ---------------------------------------------------------------- Arena

Arena::Arena(size_t initial_floats) {
  if (initial_floats) chunks_.push_back({alloc_chunk(initial_floats), 0, initial_floats});
}

static size_t round16(size_t n) { return (n + 15) / 16 * 16; }  // keep every block 64-byte aligned

Tensor Arena::take(const Shape& shape) {
  size_t n = round16(size_t(std::max<int64_t>(shape.numel(), 1)));
  for (;;) {
    // find the chunk containing used_
    for (auto& c : chunks_) {
      if (used_ >= c.begin && used_ < c.begin + c.size) {
        if (used_ + n <= c.begin + c.size) {
          float* p = c.mem.get() + (used_ - c.begin);
          used_ += n;
          peak_ = std::max(peak_, used_);
          return Tensor::view(shape, p);
        }
        used_ = c.begin + c.size;  // skip the chunk's tail; continue in the next chunk
      }
    }
    size_t end = chunks_.empty() ? 0 : chunks_.back().begin + chunks_.back().size;
    if (used_ >= end) {
      size_t grow = std::max(n, end / 2 + (size_t(1) << 20));
      chunks_.push_back({alloc_chunk(grow), end, grow});
      used_ = end;
    }
  }
}

void Arena::release(size_t mark) {
  EGOPD_CHECK(mark <= used_, "arena release past its use");
  used_ = mark;
}

void Arena::shrink_to_peak() {
  EGOPD_CHECK(used_ == 0, "arena shrink while blocks are taken");
  if (peak_ == 0 || (chunks_.size() == 1 && chunks_[0].size == peak_)) return;
  chunks_.clear();  // the old memory goes before the new chunk is allocated
  chunks_.push_back({alloc_chunk(peak_), 0, peak_});
}

size_t Arena::capacity_bytes() const {
  size_t n = 0;
  for (const auto& c : chunks_) n += c.size;
  return n * sizeof(float);
}

}  // namespace egopd
