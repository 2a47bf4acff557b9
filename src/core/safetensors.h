#pragma once
// safetensors reading (memory-mapped, header fully validated) and writing (atomic: temp file + rename).
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/dtype.h"
#include "core/tensor.h"

namespace egopd {

// Read-only memory map of a whole file.
class MappedFile {
 public:
  explicit MappedFile(const std::string& path);
  ~MappedFile();
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  const uint8_t* data() const { return data_; }
  size_t size() const { return size_; }
  const std::string& path() const { return path_; }
  // Tell the kernel the pages of [offset, offset+len) are not needed now (they stay valid and are re-read on use).
  void release_pages(size_t offset, size_t len) const;

 private:
  std::string path_;
  const uint8_t* data_ = nullptr;
  size_t size_ = 0;
};

// One tensor stored in a file: raw little-endian data of `dtype`, row-major.
struct StoredTensor {
  std::string name;
  DType dtype = DType::F32;
  std::vector<int64_t> shape;
  const uint8_t* data = nullptr;  // points into the mapping
  size_t nbytes = 0;
  std::shared_ptr<const MappedFile> file;  // keeps the mapping alive
  size_t offset = 0;                       // absolute offset in the file

  int64_t numel() const;
  std::string shape_str() const;
  // float32 copy (F32/F16/BF16 converted exactly); error naming the tensor for other dtypes.
  Tensor to_f32() const;
  // int64 copy for I64/I32 tensors.
  std::vector<int64_t> to_i64() const;
};

class SafeTensorsFile {
 public:
  // Maps and validates: header length sane (<= 100 MiB, inside the file), JSON object, known dtypes,
  // offsets inside the data section, byte size = numel x dtype size, no overlapping ranges.
  explicit SafeTensorsFile(const std::string& path);
  const std::vector<StoredTensor>& tensors() const { return tensors_; }
  const StoredTensor* find(const std::string& name) const;
  const std::string& path() const { return file_->path(); }
  const std::map<std::string, std::string>& metadata() const { return metadata_; }

 private:
  std::shared_ptr<const MappedFile> file_;
  std::vector<StoredTensor> tensors_;
  std::map<std::string, size_t> index_;
  std::map<std::string, std::string> metadata_;
};

// A tensor to write: raw bytes of `dtype` in row-major order.
struct TensorToWrite {
  std::string name;
  DType dtype;
  std::vector<int64_t> shape;
  std::vector<uint8_t> bytes;
};
TensorToWrite to_write(const std::string& name, const Tensor& t);                 // F32
TensorToWrite to_write(const std::string& name, const IdTensor& t);               // I64
TensorToWrite to_write(const std::string& name, const Tensor& t, DType as);      // F32 -> F16/BF16/F32

// Writes a safetensors file (tensors in the given order, data 8-byte aligned header) atomically.
void write_safetensors(const std::string& path, const std::vector<TensorToWrite>& tensors,
                       const std::map<std::string, std::string>& metadata = {});

// Header bytes (length prefix + JSON, padded to 8) for tensors laid out contiguously in the given order.
std::vector<uint8_t> safetensors_header(const std::vector<std::pair<std::string, std::pair<DType, std::vector<int64_t>>>>&
                                            tensors,
                                        const std::map<std::string, std::string>& metadata);

}  // namespace egopd
