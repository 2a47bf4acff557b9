#include "core/safetensors.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <set>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/json_text.h"

namespace egopd {

MappedFile::MappedFile(const std::string& path) : path_(path) {
  int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw Error(path + ": cannot open: " + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    throw Error(path + ": not a regular file");
  }
  size_ = size_t(st.st_size);
  if (size_ > 0) {
    void* p = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd, 0);
    if (p == MAP_FAILED) {
      ::close(fd);
      throw Error(path + ": mmap failed: " + std::strerror(errno));
    }
    data_ = static_cast<const uint8_t*>(p);
  }
  ::close(fd);
}

MappedFile::~MappedFile() {
  if (data_) ::munmap(const_cast<uint8_t*>(data_), size_);
}

void MappedFile::release_pages(size_t offset, size_t len) const {
  long page = ::sysconf(_SC_PAGESIZE);
  size_t begin = (offset + size_t(page) - 1) / size_t(page) * size_t(page);
  size_t end = std::min(size_, offset + len) / size_t(page) * size_t(page);
  if (end > begin) ::madvise(const_cast<uint8_t*>(data_) + begin, end - begin, MADV_DONTNEED);
}

namespace {
// Elements of a shape; -1 when the product does not fit int64. A zero dimension makes it 0 whatever the others are
// (so [2^32, 2^32, 0] is an empty tensor, not an overflow).
int64_t shape_numel(const std::vector<int64_t>& shape) {
  for (int64_t d : shape)
    if (d == 0) return 0;
  int64_t n = 1;
  for (int64_t d : shape)
    if (__builtin_mul_overflow(n, d, &n)) return -1;
  return n;
}
}  // namespace

int64_t StoredTensor::numel() const { return shape_numel(shape); }

std::string StoredTensor::shape_str() const { return shape_string(shape); }

Tensor StoredTensor::to_f32() const {
  if (!is_float_weight(dtype))
    throw Error(file->path() + ": tensor " + name + " has dtype " + dtype_name(dtype) + ", expected a float type");
  Tensor t(shape.empty() ? Shape{1} : Shape(shape));
  convert_to_f32(dtype, data, t.data(), size_t(numel()));  // convert_to_f32 reads bytes: alignment-safe via memcpy
  return t;
}

std::vector<int64_t> StoredTensor::to_i64() const {
  std::vector<int64_t> out(static_cast<size_t>(numel()));
  if (out.empty()) return out;  // an empty tensor may have no data pointer at all
  if (dtype == DType::I64) {
    std::memcpy(out.data(), data, out.size() * 8);
  } else if (dtype == DType::I32) {
    for (size_t i = 0; i < out.size(); ++i) {
      int32_t v;
      std::memcpy(&v, data + 4 * i, 4);
      out[i] = v;
    }
  } else {
    throw Error(file->path() + ": tensor " + name + " has dtype " + dtype_name(dtype) + ", expected I64 or I32");
  }
  return out;
}

SafeTensorsFile::SafeTensorsFile(const std::string& path) {
  file_ = std::make_shared<const MappedFile>(path);
  const size_t size = file_->size();
  if (size < 8) throw Error(path + ": too short for a safetensors file (" + std::to_string(size) + " bytes)");
  uint64_t n = 0;
  for (int i = 7; i >= 0; --i) n = (n << 8) | file_->data()[i];
  if (n > (uint64_t(100) << 20)) throw Error(path + ": safetensors header length " + std::to_string(n) + " is over 100 MiB");
  if (8 + n > size) throw Error(path + ": safetensors header length " + std::to_string(n) + " exceeds the file size");
  nlohmann::json header;
  // The JSON parser keeps only one value of a repeated key, so repeated tensor names are caught while parsing.
  std::string duplicate;
  std::set<std::string> names;
  const nlohmann::json::parser_callback_t track = [&](int depth, nlohmann::json::parse_event_t event,
                                                      nlohmann::json& parsed) {
    if (depth == 1 && event == nlohmann::json::parse_event_t::key && parsed.is_string() &&
        !names.insert(parsed.get<std::string>()).second && duplicate.empty())
      duplicate = parsed.get<std::string>();
    return true;
  };
  try {
    header = parse_json(std::string_view(reinterpret_cast<const char*>(file_->data()) + 8, n), track);
  } catch (const std::exception& e) {
    throw Error(path + ": safetensors header is not valid JSON");
  }
  if (!duplicate.empty()) throw Error(path + ": tensor " + duplicate + ": duplicate tensor name in the header");
  if (!header.is_object()) throw Error(path + ": safetensors header is not a JSON object");
  const size_t base = 8 + size_t(n);
  const size_t data_size = size - base;
  std::vector<std::pair<size_t, size_t>> ranges;
  for (auto it = header.begin(); it != header.end(); ++it) {
    const std::string& name = it.key();
    if (name == "__metadata__") {
      if (it->is_object())
        for (auto m = it->begin(); m != it->end(); ++m)
          if (m->is_string()) metadata_[m.key()] = m->get<std::string>();
      continue;
    }
    const auto& v = *it;
    auto bad = [&](const std::string& why) { return Error(path + ": tensor " + name + ": " + why); };
    if (!v.is_object() || !v.contains("dtype") || !v.contains("shape") || !v.contains("data_offsets"))
      throw bad("header entry needs dtype, shape and data_offsets");
    StoredTensor t;
    t.name = name;
    t.file = file_;
    if (!v["dtype"].is_string() || !dtype_from_name(v["dtype"].get<std::string>(), &t.dtype))
      throw bad("unknown dtype " + dump_json(v["dtype"]));
    if (!v["shape"].is_array()) throw bad("shape is not a list");
    for (const auto& d : v["shape"]) {
      if (!d.is_number_integer() || d.get<int64_t>() < 0) throw bad("bad shape " + dump_json(v["shape"]));
      t.shape.push_back(d.get<int64_t>());
    }
    if (t.shape.size() > 8) throw bad("rank over 8");
    const auto& off = v["data_offsets"];
    if (!off.is_array() || off.size() != 2 || !off[0].is_number_unsigned() || !off[1].is_number_unsigned())
      throw bad("data_offsets must be two non-negative integers");
    uint64_t b = off[0].get<uint64_t>(), e = off[1].get<uint64_t>();
    if (b > e || e > data_size)
      throw bad("data_offsets [" + std::to_string(b) + "," + std::to_string(e) + "] outside the data section (" +
                std::to_string(data_size) + " bytes)");
    // numel x size, guarding against overflow
    const int64_t n = shape_numel(t.shape);
    if (n < 0) throw bad("shape " + t.shape_str() + " has more elements than can be addressed");
    const unsigned __int128 want = (unsigned __int128)(uint64_t(n)) * dtype_size(t.dtype);
    if (want != (unsigned __int128)(e - b))
      throw bad("byte size " + std::to_string(e - b) + " does not match " + dtype_name(t.dtype) + " x " + t.shape_str());
    t.nbytes = size_t(e - b);
    t.offset = base + size_t(b);
    t.data = file_->data() + t.offset;
    if (index_.count(name)) throw bad("duplicate tensor name");
    index_[name] = tensors_.size();
    if (e > b) ranges.push_back({size_t(b), size_t(e)});
    tensors_.push_back(std::move(t));
  }
  std::sort(ranges.begin(), ranges.end());
  for (size_t i = 1; i < ranges.size(); ++i)
    if (ranges[i].first < ranges[i - 1].second)
      throw Error(path + ": safetensors data ranges overlap at byte " + std::to_string(ranges[i].first));
}

const StoredTensor* SafeTensorsFile::find(const std::string& name) const {
  auto it = index_.find(name);
  return it == index_.end() ? nullptr : &tensors_[it->second];
}

// ---------------------------------------------------------------- writing

TensorToWrite to_write(const std::string& name, const Tensor& t) { return to_write(name, t, DType::F32); }

TensorToWrite to_write(const std::string& name, const Tensor& t, DType as) {
  TensorToWrite w{name, as, t.shape().vec(), {}};
  const size_t n = size_t(t.numel());
  w.bytes.resize(n * dtype_size(as));
  if (as == DType::F32) {
    std::memcpy(w.bytes.data(), t.data(), n * 4);
  } else if (as == DType::F16 || as == DType::BF16) {
    for (size_t i = 0; i < n; ++i) {
      uint16_t h = as == DType::F16 ? float_to_half(t[int64_t(i)]) : float_to_bf16(t[int64_t(i)]);
      std::memcpy(w.bytes.data() + 2 * i, &h, 2);
    }
  } else {
    throw Error(std::string("cannot write a float tensor as ") + dtype_name(as));
  }
  return w;
}

TensorToWrite to_write(const std::string& name, const IdTensor& t) {
  TensorToWrite w{name, DType::I64, t.shape.vec(), {}};
  w.bytes.resize(t.values.size() * 8);
  std::memcpy(w.bytes.data(), t.values.data(), w.bytes.size());
  return w;
}

std::vector<uint8_t> safetensors_header(
    const std::vector<std::pair<std::string, std::pair<DType, std::vector<int64_t>>>>& tensors,
    const std::map<std::string, std::string>& metadata) {
  nlohmann::ordered_json header = nlohmann::ordered_json::object();
  if (!metadata.empty()) header["__metadata__"] = metadata;
  size_t off = 0;
  for (const auto& [name, spec] : tensors) {
    int64_t numel = 1;
    for (int64_t d : spec.second) numel *= d;
    const size_t bytes = size_t(numel) * dtype_size(spec.first);
    if (header.contains(name)) throw Error("duplicate tensor name " + name);
    header[name] = {{"dtype", dtype_name(spec.first)}, {"shape", spec.second}, {"data_offsets", {off, off + bytes}}};
    off += bytes;
  }
  std::string h = dump_json(header);
  while ((8 + h.size()) % 8) h.push_back(' ');
  std::vector<uint8_t> out(8 + h.size());
  const uint64_t n = h.size();
  for (int i = 0; i < 8; ++i) out[size_t(i)] = uint8_t(n >> (8 * i));
  std::memcpy(out.data() + 8, h.data(), h.size());
  return out;
}

void write_safetensors(const std::string& path, const std::vector<TensorToWrite>& tensors,
                       const std::map<std::string, std::string>& metadata) {
  std::vector<std::pair<std::string, std::pair<DType, std::vector<int64_t>>>> specs;
  for (const auto& t : tensors) {
    int64_t numel = 1;
    for (int64_t d : t.shape) numel *= d;
    if (size_t(numel) * dtype_size(t.dtype) != t.bytes.size())
      throw Error(path + ": tensor " + t.name + ": byte count does not match its shape");
    specs.push_back({t.name, {t.dtype, t.shape}});
  }
  std::vector<uint8_t> header;
  try {
    header = safetensors_header(specs, metadata);
  } catch (const Error& e) {
    throw Error(path + ": " + e.what());
  }
  AtomicFileWriter w(path);
  w.write(header.data(), header.size());
  for (const auto& t : tensors) w.write(t.bytes.data(), t.bytes.size());
  w.commit();
}

}  // namespace egopd
