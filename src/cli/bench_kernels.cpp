// `egopd bench gemm` and `egopd bench conv2d`: one kernel call timed R times after a warm-up; the report gives
// the median seconds per call and the GFLOP per call (2*M*N*K; convolutions 2 * outputs * cin*kh*kw, also for
// Winograd, whose GFLOP/s are therefore direct-equivalent).
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "core/cpu.h"
#include "core/dtype.h"
#include "core/error.h"
#include "core/kernels/conv.h"
#include "core/kernels/gemm.h"
#include "core/threading.h"

namespace egopd {

namespace {

DType weight_dtype(const Args& a, const std::string& target) {
  const std::string s = a.get("dtype", "f32");
  if (s == "f32") return DType::F32;
  if (s == "f16") return DType::F16;
  if (s == "bf16") return DType::BF16;
  throw Error("bench " + target + ": --dtype must be f32, f16 or bf16 (got '" + s + "')");
}

int64_t positive(const Args& a, const std::string& target, const std::string& name, int64_t fallback,
                 int64_t max = int64_t(1) << 20) {
  if (fallback <= 0) a.require(name);  // required option: one-line error when missing
  const int64_t v = a.get_int(name, fallback);
  if (v < 1 || v > max)
    throw Error("bench " + target + ": --" + name + " must be between 1 and " + std::to_string(max) + " (got " +
                std::to_string(v) + ")");
  return v;
}

// Weights in the requested storage dtype: float32 values or their F16/BF16 encodings.
struct BenchWeights {
  std::vector<float> f32;
  std::vector<uint16_t> h16;
  DType dtype;
  BenchWeights(size_t n, DType dt, uint32_t seed) : dtype(dt) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    f32.resize(n);
    for (auto& v : f32) v = u(rng);
    if (dt != DType::F32) {
      h16.resize(n);
      for (size_t i = 0; i < n; ++i) h16[i] = dt == DType::F16 ? float_to_half(f32[i]) : float_to_bf16(f32[i]);
      f32 = {};
    }
  }
  const void* data() const { return dtype == DType::F32 ? static_cast<const void*>(f32.data()) : h16.data(); }
};

std::vector<float> random_floats(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> v(n);
  for (auto& x : v) x = u(rng);
  return v;
}


}  // namespace

int bench_gemm(const Args& a) {
  const int64_t M = positive(a, "gemm", "m", 0), N = positive(a, "gemm", "n", 0), K = positive(a, "gemm", "k", 0);
  const DType dt = weight_dtype(a, "gemm");
  const bool trans_b = a.flag("trans-b"), geglu = a.flag("geglu");
  const int64_t repeat = positive(a, "gemm", "repeat", 10, 100000);
  const bool json = a.flag("json");
  a.finish();
  if (double(M) * K + double(K) * N + double(M) * N > 2e9) throw Error("bench gemm: matrices too large (> 2e9 floats)");
  if (geglu && N % 2 != 0) throw Error("bench gemm: --geglu needs an even --n (value and gate columns)");

  const std::vector<float> A = random_floats(size_t(M * K), 1);
  const BenchWeights B(size_t(K * N), dt, 2);
  std::vector<float> C(size_t(M * N));
  const Operand bop{B.data(), dt, trans_b ? K : N, trans_b, nullptr};  // W [N,K] with --trans-b, else [K,N]
  // --geglu: the feed-forward's projection, [M, N / 2] = GEGLU of the [M, N] product (value | gate columns).
  std::vector<float> scratch(geglu && gemm_geglu_needs_scratch(N / 2, K) ? size_t(M * N) : 0);
  const CallTimes s = median_call_times(repeat, true, [&] {
    if (geglu) return gemm_geglu(M, N / 2, K, f32_operand(A.data(), K), bop, nullptr, C.data(), N / 2, scratch.data());
    gemm(M, N, K, f32_operand(A.data(), K), bop, C.data(), N);
  });

  BenchReport r;
  r.target = "gemm";
  r.seconds = s.wall;
  r.cpu_seconds = s.cpu;
  r.gflop = 2.0 * double(M) * double(N) * double(K) * 1e-9;
  r.threads = num_threads();
  r.extra["m"] = M;
  r.extra["n"] = N;
  r.extra["k"] = K;
  r.extra["dtype"] = dtype_name(dt);
  r.extra["trans_b"] = trans_b;
  r.extra["geglu"] = geglu;
  r.extra["repeat"] = repeat;
  print_bench_report(r, json);
  return 0;
}

int bench_conv2d(const Args& a) {
  const int64_t n = positive(a, "conv2d", "frames", 0, 4096), cin = positive(a, "conv2d", "cin", 0, 65536),
                cout = positive(a, "conv2d", "cout", 0, 65536), h = positive(a, "conv2d", "h", 0, 16384),
                w = positive(a, "conv2d", "w", 0, 16384), kernel = positive(a, "conv2d", "kernel", 3, 64),
                stride = positive(a, "conv2d", "stride", 1, 64);
  const DType dt = weight_dtype(a, "conv2d");
  const int64_t repeat = positive(a, "conv2d", "repeat", 10, 100000);
  const bool json = a.flag("json");
  a.finish();
  const Conv2dGeom g{cin, cout, kernel, kernel, stride, stride, kernel / 2, kernel / 2};  // "same" padding
  const int64_t oh = g.out_h(h), ow = g.out_w(w);
  if (oh < 1 || ow < 1) throw Error("bench conv2d: the kernel does not fit the image");
  if (double(n) * (cin * h * w + cout * oh * ow) > 2e9) throw Error("bench conv2d: tensors too large (> 2e9 floats)");

  const std::vector<float> x = random_floats(size_t(n * cin * h * w), 3), bias = random_floats(size_t(cout), 5);
  const BenchWeights W(size_t(cout * cin * kernel * kernel), dt, 4);
  std::vector<float> y(size_t(n * cout * oh * ow));
  const Operand wop{W.data(), dt, cin * kernel * kernel, false, nullptr};
  const CallTimes s = median_call_times(repeat, true, [&] { conv2d(x.data(), n, h, w, wop, bias.data(), g, y.data()); });

  BenchReport r;
  r.target = "conv2d";
  r.seconds = s.wall;
  r.cpu_seconds = s.cpu;
  r.gflop = 2.0 * double(n) * double(cout) * double(oh * ow) * double(cin * kernel * kernel) * 1e-9;
  r.threads = num_threads();
  r.extra["frames"] = n;
  r.extra["cin"] = cin;
  r.extra["cout"] = cout;
  r.extra["h"] = h;
  r.extra["w"] = w;
  r.extra["kernel"] = kernel;
  r.extra["stride"] = stride;
  r.extra["conv_algorithm"] = conv2d_algorithm(g, n, h, w);  // GFLOP/s are direct-equivalent for Winograd
  r.extra["dtype"] = dtype_name(dt);
  r.extra["repeat"] = repeat;
    print_bench_report(r, json);
  return 0;
}

}  // namespace egopd
