#include "convert/dtype_convert.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <set>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/finite_check.h"

namespace egopd {
namespace fs = std::filesystem;

namespace {

bool ends_with(const std::string& s, const std::string& t) {
  return s.size() >= t.size() && s.compare(s.size() - t.size(), t.size(), t) == 0;
}

DType float_dtype(TargetDType t) {
  return t == TargetDType::F16 ? DType::F16 : t == TargetDType::BF16 ? DType::BF16 : DType::F32;
}

// Converts finite values (see stored_values); a value too large for the target type is an error naming the tensor,
// never an Inf in the converted model.
void store_floats(const float* v, size_t n, DType dt, uint8_t* dst, const std::string& name) {
  if (dt == DType::F32) {
    std::memcpy(dst, v, n * 4);
    return;
  }
  constexpr size_t kChunk = 4096;
  uint16_t h[kChunk];
  for (size_t c0 = 0; c0 < n; c0 += kChunk) {
    const size_t len = std::min(kChunk, n - c0);
    if (dt == DType::F16) {
      floats_to_halves(v + c0, h, len);
    } else {
      for (size_t i = 0; i < len; ++i) h[i] = float_to_bf16(v[c0 + i]);
    }
    for (size_t i = 0; i < len; ++i)
      if ((h[i] & 0x7fffu) == (dt == DType::F16 ? 0x7c00u : 0x7f80u))  // ±Inf of the target from a finite value
        throw Error(name + ": value " + std::to_string(v[c0 + i]) + " at index " + std::to_string(c0 + i) +
                    " overflows " + dtype_name(dt) + (dt == DType::F16 ? " (largest 65504)" : "") +
                    "; keep this model in a wider type");
    std::memcpy(dst + 2 * c0, h, 2 * len);
  }
}

// float32 values of a stored tensor: float types converted exactly, I8 dequantised with its scales.
std::vector<float> stored_values(const WeightMap& w, const StoredTensor& t) {
  std::vector<float> v(size_t(t.numel()));
  if (t.dtype == DType::I8) {
    const StoredTensor* s = w.find(t.name + "_scale");
    const int64_t rows = t.shape.empty() ? 1 : t.shape[0];
    if (!s || s->dtype != DType::F32 || s->numel() != rows)
      throw Error(w.label() + ": int8 tensor " + t.name + " needs " + t.name + "_scale (F32 [" + std::to_string(rows) + "])");
    std::vector<float> scale(static_cast<size_t>(rows));
    std::memcpy(scale.data(), s->data, size_t(rows) * 4);
    const int64_t cols = rows ? t.numel() / rows : 0;
    for (int64_t r = 0; r < rows; ++r)
      for (int64_t c = 0; c < cols; ++c) {
        int8_t q;
        std::memcpy(&q, t.data + r * cols + c, 1);
        v[size_t(r * cols + c)] = float(q) * scale[size_t(r)];
      }
  } else {
    convert_to_f32(t.dtype, t.data, v.data(), v.size());
  }
  release_stored(t);
  // A NaN or Inf would be carried into the converted model (or quantised to zeros with scale 0): refuse.
  if (const int64_t bad = count_non_finite(v.data(), int64_t(v.size())))
    throw Error(w.label() + ": tensor " + t.name + " holds " + std::to_string(bad) +
                " NaN/Inf values; the weights are broken (egopd-convert inspect lists them)");
  return v;
}

}  // namespace

TargetDType parse_target_dtype(const std::string& s) {
  if (s == "f32") return TargetDType::F32;
  if (s == "f16") return TargetDType::F16;
  if (s == "bf16") return TargetDType::BF16;
  if (s == "q8") return TargetDType::Q8;
  throw Error("unknown target dtype '" + s + "' (f32, f16, bf16 or q8)");
}

bool is_q8_quantizable(const std::string& key, const std::vector<int64_t>& shape) {
  if (shape.size() < 2 || !ends_with(key, ".weight")) return false;
  return !ends_with(key, "token_embedding.weight") && !ends_with(key, "position_embedding.weight");
}

void quantize_rows_q8(const float* w, int64_t rows, int64_t cols, int8_t* q, float* scale) {
  for (int64_t r = 0; r < rows; ++r) {
    const float* row = w + r * cols;
    float m = 0.0f;
    for (int64_t c = 0; c < cols; ++c) m = std::max(m, std::fabs(row[c]));
    const float s = m / 127.0f;
    scale[r] = s;
    for (int64_t c = 0; c < cols; ++c) {
      // Division in double so the largest element lands exactly on +-127; nearbyint rounds half to even.
      const double v = s > 0.0f ? std::nearbyint(double(row[c]) / double(s)) : 0.0;
      q[r * cols + c] = int8_t(std::clamp(v, -127.0, 127.0));
    }
  }
}

std::vector<OutTensor> converted_tensors(const WeightMap& w, TargetDType to, DTypeReport* report) {
  std::vector<OutTensor> out;
  for (const auto& key : w.keys()) {
    const StoredTensor* t = w.find(key);
    if (ends_with(key, "_scale")) {  // travels with its I8 tensor
      const StoredTensor* base = w.find(key.substr(0, key.size() - 6));
      if (base && base->dtype == DType::I8) continue;
    }
    ++report->tensors;
    const int64_t rows = t->shape.empty() ? 1 : t->shape[0];
    const int64_t cols = rows ? t->numel() / rows : 0;
    const bool is_float = is_float_weight(t->dtype) || t->dtype == DType::I8;
    if (!is_float) {  // ids, masks: unchanged
      out.push_back({key, t->dtype, t->shape, [t](uint8_t* dst) { copy_stored(*t, dst); }});
      continue;
    }
    if (to == TargetDType::Q8 && t->dtype == DType::I8) {
      const StoredTensor* s = w.find(key + "_scale");
      if (!s) throw Error(w.label() + ": int8 tensor " + key + " has no " + key + "_scale");
      out.push_back({key, DType::I8, t->shape, [t](uint8_t* dst) { copy_stored(*t, dst); }});
      out.push_back({key + "_scale", s->dtype, s->shape, [s](uint8_t* dst) { copy_stored(*s, dst); }});
      continue;
    }
    if (to == TargetDType::Q8 && is_q8_quantizable(key, t->shape)) {
      ++report->quantized;
      // Each fill recomputes the quantisation, so the two tensors may be written in any order or shard.
      const WeightMap* wm = &w;
      out.push_back({key, DType::I8, t->shape, [wm, t, rows, cols](uint8_t* dst) {
                       const std::vector<float> v = stored_values(*wm, *t);
                       std::vector<float> scale(static_cast<size_t>(rows));
                       quantize_rows_q8(v.data(), rows, cols, reinterpret_cast<int8_t*>(dst), scale.data());
                     }});
      out.push_back({key + "_scale", DType::F32, {rows}, [wm, t, rows, cols](uint8_t* dst) {
                       const std::vector<float> v = stored_values(*wm, *t);
                       std::vector<int8_t> q(v.size());
                       quantize_rows_q8(v.data(), rows, cols, q.data(), reinterpret_cast<float*>(dst));
                     }});
      continue;
    }
    // Float target (q8 keeps non-quantised float tensors in their stored dtype).
    const DType dt = to == TargetDType::Q8 ? (t->dtype == DType::I8 ? DType::F32 : t->dtype) : float_dtype(to);
    const WeightMap* wm = &w;
    out.push_back({key, dt, t->shape, [wm, t, dt](uint8_t* dst) {
                     if (t->dtype == dt) return copy_stored(*t, dst);
                     const std::vector<float> v = stored_values(*wm, *t);
                     store_floats(v.data(), v.size(), dt, dst, wm->label() + ": tensor " + t->name);
                   }});
  }
  return out;
}

namespace {

const std::string kIndexSuffix = ".safetensors.index.json";
const std::string kFileSuffix = ".safetensors";

bool is_shard_name(const std::string& base) {  // "<stem>-00001-of-00003"
  const size_t of = base.rfind("-of-");
  return of != std::string::npos && of >= 6 && base[of - 6] == '-';
}

// Weight stems of one folder: "<stem>.safetensors", "<stem>.safetensors.index.json" or a .fp16/.bf16 variant.
std::set<std::string> weight_stems(const fs::path& dir) {
  std::set<std::string> stems;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    const std::string f = e.path().filename().string();
    if (f.find(".tmp.") != std::string::npos) continue;
    if (ends_with(f, kIndexSuffix)) {
      stems.insert(f.substr(0, f.size() - kIndexSuffix.size()));
    } else if (ends_with(f, kFileSuffix)) {
      std::string base = f.substr(0, f.size() - kFileSuffix.size());
      if (is_shard_name(base)) continue;  // reached through its index
      if (ends_with(base, ".fp16") || ends_with(base, ".bf16")) base = base.substr(0, base.size() - 5);
      stems.insert(base);
    }
  }
  return stems;
}

bool is_weight_file(const std::string& f) { return ends_with(f, kFileSuffix) || ends_with(f, kIndexSuffix); }

void convert_map(const WeightMap& w, const fs::path& out_dir, const std::string& stem, TargetDType to,
                 const WriteOptions& write, DTypeReport* report) {
  report->bytes_in += w.total_bytes();
  const std::vector<OutTensor> tensors = converted_tensors(w, to, report);
  for (const auto& t : tensors) report->bytes_out += t.nbytes();
  write_weights(out_dir.string(), stem, tensors, write);
  ++report->files;
}

void convert_folder(const fs::path& in, const fs::path& out, TargetDType to, const WriteOptions& write,
                    DTypeReport* report) {
  fs::create_directories(out);
  for (const auto& stem : weight_stems(in)) {
    const WeightMap w = open_weights_dir(in.string(), stem, (in.filename() / stem).string());
    convert_map(w, out, stem, to, write, report);
  }
  for (const auto& e : fs::directory_iterator(in)) {
    const std::string f = e.path().filename().string();
    if (e.is_directory()) {
      convert_folder(e.path(), out / f, to, write, report);
    } else if (e.is_regular_file() && !is_weight_file(f) && f.find(".tmp.") == std::string::npos) {
      copy_file_atomic(e.path().string(), (out / f).string());
      ++report->copied_files;
    }
  }
}

}  // namespace

DTypeReport convert_dtype(const std::string& in, const std::string& out, TargetDType to, const WriteOptions& write) {
  DTypeReport report;
  std::error_code ec;
  if (fs::exists(out) && fs::equivalent(in, out, ec))
    throw Error("dtype: --out " + out + " is the input; write the converted model somewhere else");
  if (fs::is_directory(in)) {
    convert_folder(in, out, to, write, &report);
    return report;
  }
  // One file (or index): the output names its file or its index; the stem follows the output name.
  const WeightMap w = open_weights_path(in, fs::path(in).filename().string());
  std::string name = fs::path(out).filename().string();
  for (const std::string& s : {kIndexSuffix, kFileSuffix})
    if (ends_with(name, s)) {
      name = name.substr(0, name.size() - s.size());
      break;
    }
  const fs::path parent = fs::path(out).has_parent_path() ? fs::path(out).parent_path() : fs::path(".");
  convert_map(w, parent, name, to, write, &report);
  return report;
}

}  // namespace egopd
