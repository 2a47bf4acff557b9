#include "core/weights.h"

#include <cstring>
#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "core/json_text.h"

namespace egopd {
namespace fs = std::filesystem;

WeightView WeightView::sub(const std::string& name) const { return WeightView(map_, key(name)); }

void WeightView::release() const { map_->release(prefix_); }

bool WeightView::has(const std::string& name) const { return map_->find(key(name)) != nullptr; }

WeightMap WeightMap::recorder(const std::string& label) {
  WeightMap m;
  m.label_ = label;
  m.recording_ = true;
  return m;
}

WeightRef WeightView::get(const std::string& name, const Shape& expected) const {
  const std::string k = key(name);
  if (map_->recording()) {
    map_->record(k, expected);
    WeightRef r;
    r.key = k;
    r.shape = expected;
    return r;
  }
  const StoredTensor* t = map_->find(k);
  if (!t) throw Error(map_->label() + ": missing tensor " + k + " (expected shape " + expected.str() + ")");
  std::vector<int64_t> want = expected.vec();
  if (t->shape != want)
    throw Error(map_->label() + ": tensor " + k + " has shape " + shape_string(t->shape) + ", expected " + expected.str());
  WeightRef r;
  r.key = k;
  r.dtype = t->dtype;
  r.shape = expected;
  r.stored = t;
  if (t->dtype == DType::I8) {
    const std::string sk = k + "_scale";
    const StoredTensor* s = map_->find(sk);
    if (!s) throw Error(map_->label() + ": int8 tensor " + k + " has no " + sk);
    if (s->dtype != DType::F32 || s->shape != std::vector<int64_t>{expected[0]})
      throw Error(map_->label() + ": tensor " + sk + " must be F32 [" + std::to_string(expected[0]) + "], got " +
                  dtype_name(s->dtype) + " " + shape_string(s->shape));
    map_->mark_used(sk);
    r.scale = static_cast<const float*>(map_->aligned_data(*s));
  } else if (!is_float_weight(t->dtype)) {
    throw Error(map_->label() + ": tensor " + k + " has dtype " + dtype_name(t->dtype) + ", expected F32, F16 or BF16");
  }
  r.data = map_->aligned_data(*t);
  map_->mark_used(k);
  return r;
}

Tensor WeightView::get_f32(const std::string& name, const Shape& expected) const {
  WeightRef r = get(name, expected);
  if (map_->recording()) return Tensor::zeros(expected);
  Tensor out(expected);
  if (r.dtype == DType::I8) {
    const int64_t rows = expected[0], cols = expected.numel() / std::max<int64_t>(rows, 1);
    const auto* q = static_cast<const int8_t*>(r.data);
    for (int64_t i = 0; i < rows; ++i)
      for (int64_t j = 0; j < cols; ++j) out[i * cols + j] = float(q[i * cols + j]) * r.scale[i];
  } else {
    convert_to_f32(r.dtype, r.data, out.data(), size_t(expected.numel()));
  }
  return out;
}

const StoredTensor* WeightMap::find(const std::string& key) const {
  auto it = index_.find(key);
  return it == index_.end() ? nullptr : it->second;
}

std::vector<std::string> WeightMap::keys() const {
  std::vector<std::string> k;
  for (const auto& [name, t] : index_) k.push_back(name);
  return k;
}

std::vector<std::string> WeightMap::unused_keys() const {
  std::vector<std::string> k;
  for (const auto& [name, t] : index_)
    if (!used_.count(name)) k.push_back(name);
  return k;
}

void WeightMap::check_all_used(const std::vector<std::string>& tolerated) const {
  if (recording_) return;
  for (const auto& k : unused_keys()) {
    bool ok = false;
    for (const auto& t : tolerated) ok = ok || k.find(t) != std::string::npos;
    if (!ok) throw Error(label_ + ": unexpected tensor " + k + " (not part of the configured architecture)");
  }
}

uint64_t WeightMap::total_bytes() const {
  uint64_t n = 0;
  for (const auto& [name, t] : index_) n += t->nbytes;
  return n;
}

uint64_t WeightMap::release(const std::string& prefix) const {
  uint64_t n = 0;
  // index_ is sorted, so the keys under a prefix are one contiguous range starting at lower_bound(prefix).
  for (auto it = index_.lower_bound(prefix); it != index_.end(); ++it) {
    const std::string& k = it->first;
    if (k.compare(0, prefix.size(), prefix) != 0) break;
    if (!prefix.empty() && k.size() > prefix.size() && k[prefix.size()] != '.') continue;  // "blocks.1" vs "blocks.10"
    const StoredTensor* t = it->second;
    if (t->file) t->file->release_pages(t->offset, t->nbytes);
    n += t->nbytes;
  }
  return n;
}

const void* WeightMap::aligned_data(const StoredTensor& t) const {
  size_t align = std::max<size_t>(dtype_size(t.dtype), 1);
  if (reinterpret_cast<uintptr_t>(t.data) % align == 0) return t.data;
  std::shared_ptr<uint8_t[]> copy(new uint8_t[std::max<size_t>(t.nbytes, 8) + 8]);
  uint8_t* p = copy.get();
  while (reinterpret_cast<uintptr_t>(p) % 8) ++p;
  if (t.nbytes > 0) std::memcpy(p, t.data, t.nbytes);
  copies_.push_back(copy);
  return p;
}

WeightMap WeightMap::load_file(const std::string& path, const std::string& label) {
  WeightMap m;
  m.label_ = label;
  auto f = std::make_shared<SafeTensorsFile>(path);
  for (const auto& t : f->tensors()) m.index_[t.name] = &t;
  m.files_.push_back(f);
  return m;
}

WeightMap WeightMap::load_dir(const std::string& dir, const std::string& stem, const std::string& label) {
  const fs::path d(dir);
  if (!fs::is_directory(d)) throw Error(label + ": model folder " + dir + " does not exist");
  const fs::path single = d / (stem + ".safetensors");
  if (fs::exists(single)) return load_file(single.string(), label);
  const fs::path index = d / (stem + ".safetensors.index.json");
  if (fs::exists(index)) {
    nlohmann::json j;
    try {
      std::ifstream in(index);
      j = parse_json(in);
    } catch (const std::exception&) {
      throw Error(index.string() + ": not valid JSON");
    }
    if (!j.contains("weight_map") || !j["weight_map"].is_object())
      throw Error(index.string() + ": no \"weight_map\" object");
    WeightMap m;
    m.label_ = label;
    std::map<std::string, std::shared_ptr<SafeTensorsFile>> shards;
    for (auto it = j["weight_map"].begin(); it != j["weight_map"].end(); ++it) {
      if (!it->is_string()) throw Error(index.string() + ": weight_map entry " + it.key() + " is not a file name");
      const std::string shard = it->get<std::string>();
      if (shard.find('/') != std::string::npos || shard.find("..") != std::string::npos)
        throw Error(index.string() + ": shard name " + shard + " must be a plain file name");
      auto& f = shards[shard];
      if (!f) {
        f = std::make_shared<SafeTensorsFile>((d / shard).string());
        m.files_.push_back(f);
      }
      const StoredTensor* t = f->find(it.key());
      if (!t) throw Error((d / shard).string() + ": tensor " + it.key() + " listed in the index is not in the shard");
      m.index_[it.key()] = t;
    }
    return m;
  }
  for (const char* variant : {".fp16", ".bf16"}) {
    const fs::path v = d / (stem + variant + ".safetensors");
    if (fs::exists(v)) return load_file(v.string(), label);
  }
  throw Error(label + ": no " + stem + ".safetensors (or sharded index, or .fp16/.bf16 variant) in " + dir);
}

}  // namespace egopd
