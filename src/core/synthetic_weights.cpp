#include "core/synthetic_weights.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/hash.h"
#include "core/safetensors.h"

namespace egopd {

static uint64_t splitmix64(uint64_t& s) {
  uint64_t z = (s += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

static bool ends_with(const std::string& s, const std::string& t) {
  return s.size() >= t.size() && s.compare(s.size() - t.size(), t.size(), t) == 0;
}

void synthetic_values(const std::string& name, const Shape& shape, uint64_t seed, float* out) {
  const int64_t n = shape.numel();
  if (ends_with(name, "mix_factor")) {
    std::fill(out, out + n, 0.0f);
    return;
  }
  const bool one_d = shape.ndim() <= 1;
  if (one_d && ends_with(name, ".weight")) {  // norm scales
    std::fill(out, out + n, 1.0f);
    return;
  }
  const double bound = one_d ? 0.02 : 1.0 / std::sqrt(double(std::max<int64_t>(1, n / shape[0])));
  const uint64_t base = fnv1a(name) ^ (seed * 0x2545f4914f6cdd1dull);
  constexpr int64_t kChunk = 1 << 16;  // independent streams per chunk so generation parallelises
#pragma omp parallel for schedule(static) if (n > 4 * kChunk)
  for (int64_t c0 = 0; c0 < n; c0 += kChunk) {
    uint64_t s = base + uint64_t(c0);
    const int64_t c1 = std::min(n, c0 + kChunk);
    for (int64_t i = c0; i < c1; ++i) {
      const double u = double(splitmix64(s) >> 11) * 0x1.0p-53;  // [0, 1)
      out[i] = float((2.0 * u - 1.0) * bound);
    }
  }
}

// A hash of what synthetic_values writes for probes that reach each of its cases (a mix factor, a norm scale, a
// bias, a matrix of several parallel chunks), so that a cache key changes with the generator itself: a build whose
// values differ never reuses another build's cached file.
static uint64_t generator_fingerprint() {
  static const uint64_t fingerprint = [] {
    const std::pair<const char*, Shape> probes[] = {{"probe.mix_factor", Shape{3}},
                                                    {"probe.norm.weight", Shape{5}},
                                                    {"probe.bias", Shape{7}},
                                                    {"probe.weight", Shape{5, 1 << 16}}};
    uint64_t h = kFnv1aBasis;
    std::vector<float> values;
    for (const auto& [name, shape] : probes) {
      values.resize(size_t(shape.numel()));
      synthetic_values(name, shape, 1234, values.data());
      h = fnv1a(values.data(), values.size() * sizeof(float), h);
    }
    return h;
  }();
  return fingerprint;
}

std::string synthetic_weights_id(const std::vector<std::pair<std::string, Shape>>& params, DType dtype,
                                 uint64_t seed) {
  std::string key = dtype_name(dtype);
  key.append(" ").append(std::to_string(seed)).append(" ").append(std::to_string(generator_fingerprint()));
  for (const auto& [name, shape] : params) {
    key.append(";").append(name);
    for (int64_t d : shape.vec()) key.append(" ").append(std::to_string(d));
  }
  return hex16(fnv1a(key));
}

void write_synthetic_safetensors(const std::string& path, const std::vector<std::pair<std::string, Shape>>& params,
                                 DType dtype, uint64_t seed) {
  if (!is_float_weight(dtype)) throw Error(path + ": synthetic weights must be F32, F16 or BF16");
  std::vector<std::pair<std::string, std::pair<DType, std::vector<int64_t>>>> specs;
  int64_t largest = 1;
  for (const auto& [name, shape] : params) {
    specs.push_back({name, {dtype, shape.vec()}});
    largest = std::max(largest, shape.numel());
  }
  std::vector<uint8_t> header = safetensors_header(specs, {{"format", "pt"}, {"egopd", "synthetic"}});
  AtomicFileWriter w(path);
  w.write(header.data(), header.size());
  std::vector<float> values(static_cast<size_t>(largest));
  std::vector<uint8_t> bytes(static_cast<size_t>(largest) * dtype_size(dtype));
  for (const auto& [name, shape] : params) {
    const int64_t n = shape.numel();
    synthetic_values(name, shape, seed, values.data());
    if (dtype == DType::F32) {
      std::memcpy(bytes.data(), values.data(), size_t(n) * 4);
    } else {
      auto* h = reinterpret_cast<uint16_t*>(bytes.data());
      constexpr int64_t kChunk = 1 << 16;
#pragma omp parallel for schedule(static) if (n > 4 * kChunk)
      for (int64_t c0 = 0; c0 < n; c0 += kChunk) {
        const int64_t len = std::min(kChunk, n - c0);
        if (dtype == DType::F16) {
          floats_to_halves(values.data() + c0, h + c0, size_t(len));
        } else {
          for (int64_t i = c0; i < c0 + len; ++i) h[i] = float_to_bf16(values[size_t(i)]);
        }
      }
    }
    w.write(bytes.data(), size_t(n) * dtype_size(dtype));
  }
  w.commit();
}

}  // namespace egopd
