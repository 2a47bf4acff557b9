#pragma once
// Weight map: every tensor of a component (one file or a sharded checkpoint), looked up by name with the
// expected shape checked, plus prefix views that read like the parameter tree:
//   WeightView r = weights.root();  Conv2d c(r.sub("down_blocks.0.resnets.1.spatial_res_block"), "conv1", ...);
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "core/safetensors.h"
#include "core/tensor.h"

namespace egopd {

// A stored weight as the kernels consume it: raw data in its stored dtype (F32/F16/BF16, or I8 with one float scale
// per output channel), suitably aligned, memory-mapped where possible.
struct WeightRef {
  std::string key;
  DType dtype = DType::F32;
  Shape shape;
  const void* data = nullptr;
  const float* scale = nullptr;  // I8 only: [shape[0]] per-output-channel scales
  const StoredTensor* stored = nullptr;
  int64_t numel() const { return shape.numel(); }
};

class WeightMap;

class WeightView {
 public:
  WeightView(const WeightMap* map, std::string prefix) : map_(map), prefix_(std::move(prefix)) {}
  WeightView sub(const std::string& name) const;
  std::string key(const std::string& name) const { return prefix_.empty() ? name : prefix_ + "." + name; }
  const std::string& prefix() const { return prefix_; }
  bool has(const std::string& name) const;
  // Stored tensor with shape check; one-line error naming the key and both shapes.
  WeightRef get(const std::string& name, const Shape& expected) const;
  // float32 copy (norm weights, biases, small parameters).
  Tensor get_f32(const std::string& name, const Shape& expected) const;
  const WeightMap& map() const { return *map_; }
  // WeightMap::release of this prefix: the tensors under it leave RAM until their next use.
  void release() const;

 private:
  const WeightMap* map_;
  std::string prefix_;
};

class WeightMap {
 public:
  // Component folder: <stem>.safetensors, else <stem>.safetensors.index.json (sharded), else <stem>.fp16/.bf16
  // variant. `label` names the component in messages ("unet", "vae", ...).
  static WeightMap load_dir(const std::string& dir, const std::string& stem, const std::string& label);
  static WeightMap load_file(const std::string& path, const std::string& label);
  // A map with no data that records every (key, shape) a model asks for: constructing a model on it enumerates the
  // architecture's parameter tree (synthetic weights, `inspect`). get() returns null data; get_f32() zeros.
  static WeightMap recorder(const std::string& label);
  bool recording() const { return recording_; }
  const std::vector<std::pair<std::string, Shape>>& recorded() const { return recorded_; }
  void record(const std::string& key, const Shape& shape) const { recorded_.push_back({key, shape}); }

  WeightView root() const { return WeightView(this, ""); }
  const std::string& label() const { return label_; }
  const StoredTensor* find(const std::string& key) const;
  std::vector<std::string> keys() const;
  // Keys never requested through a view (for `inspect` and strict loading).
  std::vector<std::string> unused_keys() const;
  // Error if any key outside `tolerated` (glob-free: a key matches when it ends with or contains one of them, see .cpp)
  // was not used.
  void check_all_used(const std::vector<std::string>& tolerated_substrings) const;
  uint64_t total_bytes() const;
  // Drops the resident memory-mapped pages of every tensor named `prefix` or `prefix.*` (every tensor for ""):
  // the data stays valid and is read back from the file on its next use. Low-memory mode calls it after each
  // block so only the block running holds its weights in RAM. Returns the bytes of the tensors covered.
  uint64_t release(const std::string& prefix) const;

  // Internal: mark a key as used, keep an aligned copy alive.
  void mark_used(const std::string& key) const { used_.insert(key); }
  const void* aligned_data(const StoredTensor& t) const;

 private:
  std::string label_;
  std::vector<std::shared_ptr<SafeTensorsFile>> files_;
  std::map<std::string, const StoredTensor*> index_;
  mutable std::set<std::string> used_;
  mutable std::vector<std::shared_ptr<uint8_t[]>> copies_;
  bool recording_ = false;
  mutable std::vector<std::pair<std::string, Shape>> recorded_;
};

}  // namespace egopd
