#pragma once
// Weight-file plumbing of egopd-convert: opening the weight files of a component folder (weights.md §2) with a
// duplicate-name check, and writing a component's tensors as one safetensors file or as shards + index, streamed
// tensor by tensor (only one tensor is ever held in memory) and atomically.
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "core/dtype.h"
#include "core/weights.h"

namespace egopd {

// One output tensor: its bytes are produced on demand by `fill` (exactly nbytes() bytes into dst).
struct OutTensor {
  std::string name;
  DType dtype = DType::F32;
  std::vector<int64_t> shape;
  std::function<void(uint8_t* dst)> fill;
  size_t nbytes() const;
};

struct WriteOptions {
  uint64_t shard_bytes = 0;  // 0: one <stem>.safetensors; else <stem>-0000i-of-0000n.safetensors + index
  std::map<std::string, std::string> metadata{{"format", "pt"}};
};

// Writes the tensors (in the given order) to `dir`, then removes weight files of the same stem in another layout
// that would shadow the new ones (a stale single file, index, shards or .fp16/.bf16 variant). Returns the file
// names written (shards, then the index).
std::vector<std::string> write_weights(const std::string& dir, const std::string& stem,
                                       const std::vector<OutTensor>& tensors, const WriteOptions& options);

// A model (or component) folder written whole: fill(dir) writes into a temporary folder beside `out`, which is moved
// into place when complete, so a failed or interrupted conversion leaves no partial folder and an earlier model
// folder there (one holding `marker`, e.g. model_index.json) untouched; any other non-empty folder is an error.
void write_model_folder(const std::string& out, const std::string& marker,
                        const std::function<void(const std::string& dir)>& fill);

// `--shard-size MB` as bytes (0 = no sharding); error on a negative size.
uint64_t shard_bytes_from_mb(int64_t mb);

// Errors (one line, naming the file and the name) if a safetensors header lists a tensor name twice: JSON parsers
// keep only one of them silently.
void check_unique_tensor_names(const std::string& path);

// The weight files a component folder resolves to, in the runtime's order (weights.md §2): the single file, else
// the shards of the index, else a .fp16/.bf16 variant; empty if there is none.
std::vector<std::string> resolve_weight_files(const std::string& dir, const std::string& stem);

// WeightMap::load_dir / load_file after check_unique_tensor_names on every file involved.
WeightMap open_weights_dir(const std::string& dir, const std::string& stem, const std::string& label);
WeightMap open_weights_file(const std::string& path, const std::string& label);
// A path naming one .safetensors file or a sharded checkpoint's .safetensors.index.json.
WeightMap open_weights_path(const std::string& path, const std::string& label);

// A copy of the stored bytes of `t` (tensor data may be unaligned in the mapping).
void copy_stored(const StoredTensor& t, uint8_t* dst);
// Drops the mapped pages of `t` once it has been read, so streaming a real-size model keeps resident memory small.
void release_stored(const StoredTensor& t);

// Atomic copy of a whole file, streamed.
void copy_file_atomic(const std::string& from, const std::string& to);

}  // namespace egopd
