#include "convert/tensor_io.h"

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>

#include "core/atomic_file.h"
#include "core/interrupt.h"
#include "core/error.h"
#include "core/json_text.h"
#include "core/safetensors.h"

namespace egopd {
namespace fs = std::filesystem;
using nlohmann::json;

size_t OutTensor::nbytes() const {
  size_t n = dtype_size(dtype);
  for (int64_t d : shape) n *= size_t(d);
  return n;
}

uint64_t shard_bytes_from_mb(int64_t mb) {
  if (mb < 0) throw Error("--shard-size must be a positive number of MB, got " + std::to_string(mb));
  return uint64_t(mb) << 20;
}

namespace {

std::string shard_name(const std::string& stem, size_t i, size_t n) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "-%05zu-of-%05zu.safetensors", i + 1, n);
  return stem + buf;
}

// Files an index lists (plain names only); empty if the index is missing or unreadable.
std::set<std::string> index_shards(const fs::path& index) {
  std::set<std::string> out;
  std::ifstream in(index);
  if (!in) return out;
  try {
    const json j = parse_json(in);
    for (const auto& [k, v] : j.at("weight_map").items())
      if (v.is_string() && v.get<std::string>().find('/') == std::string::npos) out.insert(v.get<std::string>());
  } catch (const std::exception&) {
  }
  return out;
}

void write_one_file(const fs::path& path, const std::vector<const OutTensor*>& tensors,
                    const std::map<std::string, std::string>& metadata) {
  std::vector<std::pair<std::string, std::pair<DType, std::vector<int64_t>>>> specs;
  size_t largest = 0;
  for (const OutTensor* t : tensors) {
    specs.push_back({t->name, {t->dtype, t->shape}});
    largest = std::max(largest, t->nbytes());
  }
  std::vector<uint8_t> header;
  try {
    header = safetensors_header(specs, metadata);
  } catch (const Error& e) {
    throw Error(path.string() + ": " + e.what());
  }
  AtomicFileWriter w(path.string());
  w.write(header.data(), header.size());
  std::vector<uint8_t> buf(largest);
  for (const OutTensor* t : tensors) {
    t->fill(buf.data());
    w.write(buf.data(), t->nbytes());
  }
  w.commit();
}

}  // namespace

std::vector<std::string> write_weights(const std::string& dir, const std::string& stem,
                                       const std::vector<OutTensor>& tensors, const WriteOptions& options) {
  const fs::path d(dir);
  fs::create_directories(d);
  const fs::path index = d / (stem + ".safetensors.index.json");
  const std::set<std::string> old_shards = index_shards(index);
  std::vector<std::string> written;
  if (options.shard_bytes == 0) {
    std::vector<const OutTensor*> all;
    for (const auto& t : tensors) all.push_back(&t);
    written.push_back(stem + ".safetensors");
    write_one_file(d / written.back(), all, options.metadata);
  } else {
    // Greedy packing in order; a tensor larger than the limit gets a shard of its own.
    std::vector<std::vector<const OutTensor*>> shards(1);
    uint64_t filled = 0, total = 0;
    for (const auto& t : tensors) {
      if (!shards.back().empty() && filled + t.nbytes() > options.shard_bytes) {
        shards.emplace_back();
        filled = 0;
      }
      shards.back().push_back(&t);
      filled += t.nbytes();
      total += t.nbytes();
    }
    json weight_map = json::object();
    for (size_t i = 0; i < shards.size(); ++i) {
      written.push_back(shard_name(stem, i, shards.size()));
      write_one_file(d / written.back(), shards[i], options.metadata);
      for (const OutTensor* t : shards[i]) weight_map[t->name] = written.back();
    }
    const json j = {{"metadata", {{"total_size", total}}}, {"weight_map", weight_map}};
    write_file_atomic(index.string(), dump_json(j, 2) + "\n");
    written.push_back(index.filename().string());
  }
  // Stale files of another layout: the runtime would pick a single file before an index, an index before a variant.
  const std::set<std::string> keep(written.begin(), written.end());
  std::set<std::string> stale = old_shards;
  for (const char* s : {".safetensors", ".safetensors.index.json", ".fp16.safetensors", ".bf16.safetensors"})
    stale.insert(stem + s);
  std::error_code ec;
  for (const auto& f : stale)
    if (!keep.count(f)) fs::remove(d / f, ec);
  return written;
}

void check_unique_tensor_names(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path + ": cannot open");
  uint8_t len[8] = {};
  in.read(reinterpret_cast<char*>(len), 8);
  if (in.gcount() != 8) return;  // SafeTensorsFile reports the short file
  uint64_t n = 0;
  for (int i = 7; i >= 0; --i) n = (n << 8) | len[i];
  if (n > (uint64_t(100) << 20)) return;
  std::string header(size_t(n), '\0');
  in.read(header.data(), std::streamsize(n));
  if (uint64_t(in.gcount()) != n) return;
  std::set<std::string> seen;
  std::string duplicate;
  json::parser_callback_t cb = [&](int depth, json::parse_event_t event, json& parsed) {
    if (depth == 1 && event == json::parse_event_t::key && duplicate.empty()) {
      const std::string k = parsed.get<std::string>();
      if (!seen.insert(k).second) duplicate = k;
    }
    return true;
  };
  try {
    const json parsed = parse_json(header, cb);
    (void)parsed;
  } catch (const std::exception&) {
    return;  // SafeTensorsFile reports invalid JSON
  }
  if (!duplicate.empty()) throw Error(path + ": tensor " + duplicate + " is listed twice in the safetensors header");
}

std::vector<std::string> resolve_weight_files(const std::string& dir, const std::string& stem) {
  const fs::path d(dir);
  const fs::path single = d / (stem + ".safetensors");
  if (fs::exists(single)) return {single.string()};
  const fs::path index = d / (stem + ".safetensors.index.json");
  if (fs::exists(index)) {
    std::vector<std::string> out;
    for (const auto& s : index_shards(index)) out.push_back((d / s).string());
    return out;
  }
  for (const char* variant : {".fp16", ".bf16"}) {
    const fs::path v = d / (stem + variant + ".safetensors");
    if (fs::exists(v)) return {v.string()};
  }
  return {};
}

WeightMap open_weights_dir(const std::string& dir, const std::string& stem, const std::string& label) {
  for (const auto& f : resolve_weight_files(dir, stem))
    if (fs::exists(f)) check_unique_tensor_names(f);
  return WeightMap::load_dir(dir, stem, label);
}

WeightMap open_weights_file(const std::string& path, const std::string& label) {
  check_unique_tensor_names(path);
  return WeightMap::load_file(path, label);
}

WeightMap open_weights_path(const std::string& path, const std::string& label) {
  const std::string suffix = ".safetensors.index.json";
  const fs::path p(path);
  const std::string name = p.filename().string();
  if (name.size() > suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0) {
    const std::string dir = p.has_parent_path() ? p.parent_path().string() : ".";
    return open_weights_dir(dir, name.substr(0, name.size() - suffix.size()), label);
  }
  if (!fs::is_regular_file(p)) throw Error(path + ": no such file");
  return open_weights_file(path, label);
}

void copy_stored(const StoredTensor& t, uint8_t* dst) {
  if (t.nbytes) std::memcpy(dst, t.data, t.nbytes);
  release_stored(t);
}

void release_stored(const StoredTensor& t) {
  if (t.file && t.nbytes) t.file->release_pages(t.offset, t.nbytes);
}

void copy_file_atomic(const std::string& from, const std::string& to) {
  std::ifstream in(from, std::ios::binary);
  if (!in) throw Error(from + ": cannot open");
  AtomicFileWriter w(to);
  std::vector<char> buf(size_t(1) << 22);
  while (in) {
    in.read(buf.data(), std::streamsize(buf.size()));
    if (in.gcount() > 0) w.write(buf.data(), size_t(in.gcount()));
  }
  if (in.bad()) throw Error(from + ": read failed");
  w.commit();
}

void write_model_folder(const std::string& out, const std::string& marker,
                        const std::function<void(const std::string& dir)>& fill) {
  install_interrupt_handlers();
  AtomicDir dir(out, marker);
  dir.fill_and_commit(fill);
}

}  // namespace egopd
