#pragma once
// Float32 tensors (contiguous, row-major, up to 6-D) and the buffers behind them.
#include <array>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <string>
#include <vector>

namespace egopd {

constexpr int kMaxDims = 6;

class Shape {
 public:
  Shape() = default;
  Shape(std::initializer_list<int64_t> dims);
  explicit Shape(const std::vector<int64_t>& dims);
  int ndim() const { return n_; }
  int64_t operator[](int i) const { return d_[i]; }
  int64_t& operator[](int i) { return d_[i]; }
  int64_t numel() const;
  std::vector<int64_t> vec() const { return std::vector<int64_t>(d_.begin(), d_.begin() + n_); }
  bool operator==(const Shape& o) const;
  bool operator!=(const Shape& o) const { return !(*this == o); }
  std::string str() const;  // "[16,320,32,32]"

 private:
  std::array<int64_t, kMaxDims> d_{};
  int n_ = 0;
};

// "[16,320,32,32]": a shape in error messages (also of stored tensors, which may have more than kMaxDims dims).
std::string shape_string(const std::vector<int64_t>& dims);

// 64-byte aligned float storage, large blocks reused from the cache of freed ones (core/block_pool.h). Tensors share
// it (copying a Tensor is shallow; use clone() for a deep copy).
std::shared_ptr<float[]> alloc_floats(size_t n);

class Tensor {
 public:
  Tensor() = default;
  explicit Tensor(const Shape& shape);                 // uninitialised
  static Tensor zeros(const Shape& shape);
  static Tensor full(const Shape& shape, float v);
  static Tensor from(const Shape& shape, const std::vector<float>& values);
  // Non-owning view over memory owned elsewhere (an arena, a mapped file converted in place, ...).
  static Tensor view(const Shape& shape, float* data);

  const Shape& shape() const { return shape_; }
  int ndim() const { return shape_.ndim(); }
  int64_t dim(int i) const { return shape_[i < 0 ? i + shape_.ndim() : i]; }
  int64_t numel() const { return shape_.numel(); }
  bool empty() const { return data_ == nullptr; }
  float* data() { return data_; }
  const float* data() const { return data_; }
  float& operator[](int64_t i) { return data_[i]; }
  float operator[](int64_t i) const { return data_[i]; }

  // Same storage, new shape with the same element count.
  Tensor reshaped(const Shape& shape) const;
  Tensor clone() const;
  // True when this Tensor is the only one holding its (owned) storage: it may then be consumed destructively.
  bool sole_owner() const { return owner_ && owner_.use_count() == 1; }
  std::vector<float> to_vector() const { return std::vector<float>(data_, data_ + numel()); }

 private:
  Shape shape_;
  std::shared_ptr<float[]> owner_;
  float* data_ = nullptr;
};

// Integer tensor for token ids (the only non-float data the models consume).
struct IdTensor {
  Shape shape;
  std::vector<int64_t> values;
};

// Bump allocator for activations: take() hands out aligned float blocks; mark()/release() return to an earlier
// point, so a block's temporaries are reused by the next block. Grows by adding chunks; never moves a block.
class Arena {
 public:
  explicit Arena(size_t initial_floats = 0);
  Tensor take(const Shape& shape);  // uninitialised view valid until release() past it or reset()
  size_t mark() const { return used_; }
  void release(size_t mark);
  void reset() { release(0); }
  // With nothing taken, replaces the chunks by one of exactly the peak use so far: a pass that repeats the same
  // requests fits it (one chunk never skips a tail), and the growth slack of the first pass is given back.
  void shrink_to_peak();
  size_t peak_bytes() const { return peak_ * sizeof(float); }
  size_t capacity_bytes() const;

 private:
  struct Chunk {
    std::shared_ptr<float[]> mem;
    size_t begin;  // arena offset of the chunk's first float
    size_t size;
  };
  std::vector<Chunk> chunks_;
  size_t used_ = 0;  // in floats, over the concatenation of chunks (a block never straddles two chunks)
  size_t peak_ = 0;
};

}  // namespace egopd
