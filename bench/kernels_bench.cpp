// SGEMM and convolution throughput on the U-Net / VAE shapes, next to OpenBLAS cblas_sgemm and oneDNN's
// convolution on the same shapes in the same run (when those libraries are installed). Counter GFLOPs = 2*M*N*K
// (convolutions: 2 * out elements * cin*kh*kw) per second of wall time. Threads: EGOPD_THREADS or physical cores,
// the same count for every library.
#include <benchmark/benchmark.h>
#include <omp.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "core/cpu.h"
#include "core/dtype.h"
#include "core/kernels/conv.h"
#include "core/kernels/gemm.h"
#include "core/threading.h"

#if EGOPD_BENCH_OPENBLAS
#include <cblas.h>
#endif
#if EGOPD_BENCH_ONEDNN
#include <oneapi/dnnl/dnnl.hpp>
#endif

namespace {

using egopd::DType;

std::vector<float> random_floats(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> v(n);
  for (auto& x : v) x = u(rng);
  return v;
}

std::vector<uint16_t> to_16bit(const std::vector<float>& v, DType dt) {
  std::vector<uint16_t> h(v.size());
  for (size_t i = 0; i < v.size(); ++i) h[i] = dt == DType::F16 ? egopd::float_to_half(v[i]) : egopd::float_to_bf16(v[i]);
  return h;
}

void set_flops(benchmark::State& state, double flops_per_call) {
  state.counters["GFLOPs"] =
      benchmark::Counter(flops_per_call * 1e-9, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["threads"] = egopd::num_threads();
}

DType dtype_arg(int64_t i) { return i == 0 ? DType::F32 : i == 1 ? DType::F16 : DType::BF16; }

// Activations A [M, K] row-major times weights W [N, K] (B transposed), as Linear layers call it.
void BM_egopd_gemm(benchmark::State& state) {
  const int64_t M = state.range(0), N = state.range(1), K = state.range(2);
  const DType dt = dtype_arg(state.range(3));
  const std::vector<float> a = random_floats(size_t(M * K), 1), w = random_floats(size_t(N * K), 2);
  const std::vector<uint16_t> w16 = dt == DType::F32 ? std::vector<uint16_t>() : to_16bit(w, dt);
  std::vector<float> c(size_t(M * N));
  const egopd::Operand B{dt == DType::F32 ? static_cast<const void*>(w.data()) : w16.data(), dt, K, true, nullptr};
  for (auto _ : state) {
    egopd::gemm(M, N, K, egopd::f32_operand(a.data(), K), B, c.data(), N);
    benchmark::DoNotOptimize(c.data());
  }
  set_flops(state, 2.0 * M * N * K);
  state.SetLabel(egopd::dtype_name(dt));
}

#if EGOPD_BENCH_OPENBLAS
void BM_openblas_sgemm(benchmark::State& state) {
  const int64_t M = state.range(0), N = state.range(1), K = state.range(2);
  openblas_set_num_threads(egopd::num_threads());
  const std::vector<float> a = random_floats(size_t(M * K), 1), w = random_floats(size_t(N * K), 2);
  std::vector<float> c(size_t(M * N));
  for (auto _ : state) {
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, int(M), int(N), int(K), 1.0f, a.data(), int(K), w.data(),
                int(K), 0.0f, c.data(), int(N));
    benchmark::DoNotOptimize(c.data());
  }
  set_flops(state, 2.0 * M * N * K);
  state.SetLabel(openblas_get_corename());
}
#endif

void gemm_shapes(benchmark::internal::Benchmark* b, bool dtypes) {
  // The U-Net's linear layers; 1024 x 1280 x 5120 (feed-forward out, 8x8 latent) has A rows 20 KiB apart.
  const int64_t shapes[][3] = {{16384, 320, 320}, {16384, 2560, 320}, {16384, 320, 1280}, {4096, 640, 640},
                               {1024, 1280, 1280}, {4096, 5120, 640},  {1024, 1280, 5120}};
  for (const auto& s : shapes)
    for (int64_t d = 0; d < (dtypes ? 3 : 1); ++d) b->Args({s[0], s[1], s[2], d});
  b->ArgNames({"M", "N", "K", "dt"})->UseRealTime()->Unit(benchmark::kMillisecond);
}

// 3x3 convolution, pad 1, stride 1, NCHW frames: args frames, cin, cout, h, w, weight dtype.
void BM_egopd_conv3x3(benchmark::State& state) {
  const int64_t n = state.range(0), cin = state.range(1), cout = state.range(2), h = state.range(3),
                w = state.range(4);
  const DType dt = dtype_arg(state.range(5));
  const std::vector<float> x = random_floats(size_t(n * cin * h * w), 3), wt = random_floats(size_t(cout * cin * 9), 4),
                           bias = random_floats(size_t(cout), 5);
  const std::vector<uint16_t> w16 = dt == DType::F32 ? std::vector<uint16_t>() : to_16bit(wt, dt);
  std::vector<float> y(size_t(n * cout * h * w));
  const egopd::Operand W{dt == DType::F32 ? static_cast<const void*>(wt.data()) : w16.data(), dt, cin * 9, false,
                         nullptr};
  const egopd::Conv2dGeom g{cin, cout, 3, 3, 1, 1, 1, 1};
  for (auto _ : state) {
    egopd::conv2d(x.data(), n, h, w, W, bias.data(), g, y.data());
    benchmark::DoNotOptimize(y.data());
  }
  set_flops(state, 2.0 * n * cout * h * w * cin * 9);
  state.SetLabel(egopd::dtype_name(dt));
}

// Temporal (3,1,1) convolution on frame-major activations: args batch, frames, cin, cout, hw. EGOPD_CONV selects
// the algorithm (auto: Winograd F(4,3) on 32+ pixels per frame of 16 frames, F(2,3) in bf16 and int8); GFLOP/s
// count the direct algorithm's work.
void conv_temporal3_bench(benchmark::State& state, egopd::Precision precision) {
  egopd::set_precision(precision);
  const int64_t b = state.range(0), f = state.range(1), cin = state.range(2), cout = state.range(3),
                hw = state.range(4);
  const std::vector<float> x = random_floats(size_t(b * f * cin * hw), 6), wt = random_floats(size_t(cout * cin * 3), 7),
                           bias = random_floats(size_t(cout), 8);
  const std::vector<uint16_t> w16 = to_16bit(wt, DType::F16);
  std::vector<float> y(size_t(b * f * cout * hw));
  const egopd::Operand W{w16.data(), DType::F16, cin * 3, false, nullptr};
  for (auto _ : state) {
    egopd::conv_temporal3(x.data(), b, f, cin, hw, W, bias.data(), cout, y.data());
    benchmark::DoNotOptimize(y.data());
  }
  // Useful work only: the first and last frame have two taps.
  set_flops(state, 2.0 * b * cout * hw * cin * (3 * f - 2));
  state.SetLabel(std::string("F16 ") + egopd::precision_name(precision));
  egopd::set_precision(egopd::Precision::Fp32);
}
void BM_egopd_conv_temporal3(benchmark::State& state) { conv_temporal3_bench(state, egopd::Precision::Fp32); }
void BM_egopd_conv_temporal3_bf16(benchmark::State& state) { conv_temporal3_bench(state, egopd::Precision::Bf16); }
void BM_egopd_conv_temporal3_int8(benchmark::State& state) { conv_temporal3_bench(state, egopd::Precision::Int8); }

#if EGOPD_BENCH_ONEDNN
// oneDNN convolution, f32, bias, forward inference. range(5): 0 = direct on plain NCHW activations (our layout),
// 1 = direct on oneDNN's preferred blocked layouts (activation reorders not timed; weights always reordered once,
// untimed), 2 = Winograd on blocked layouts (skipped where this oneDNN has no Winograd for the CPU). egopd's
// convolution runs the algorithm EGOPD_CONV selects (auto: Winograd on these shapes; direct to compare kernels).
void BM_onednn_conv3x3(benchmark::State& state) {
  using namespace dnnl;
  const int64_t n = state.range(0), cin = state.range(1), cout = state.range(2), h = state.range(3),
                w = state.range(4);
  const bool blocked = state.range(5) >= 1, winograd = state.range(5) == 2;
  omp_set_num_threads(egopd::num_threads());
  engine eng(engine::kind::cpu, 0);
  stream s(eng);
  using tag = memory::format_tag;
  using dtp = memory::data_type;
  const memory::dims src_d{n, cin, h, w}, wei_d{cout, cin, 3, 3}, bias_d{cout}, dst_d{n, cout, h, w};
  const memory::desc src_md(src_d, dtp::f32, blocked ? tag::any : tag::nchw);
  const memory::desc dst_md(dst_d, dtp::f32, blocked ? tag::any : tag::nchw);
  const memory::desc wei_md(wei_d, dtp::f32, tag::any), bias_md(bias_d, dtp::f32, tag::x);
  const convolution_forward::desc desc(prop_kind::forward_inference,
                                       winograd ? algorithm::convolution_winograd : algorithm::convolution_direct,
                                       src_md, wei_md, bias_md, dst_md, {1, 1}, {1, 1}, {1, 1});
  convolution_forward::primitive_desc pd;
  try {
    pd = convolution_forward::primitive_desc(desc, eng);
  } catch (const dnnl::error&) {
    state.SkipWithError("no oneDNN implementation of this algorithm on this CPU");
    return;
  }
  std::vector<float> x = random_floats(size_t(n * cin * h * w), 3), wt = random_floats(size_t(cout * cin * 9), 4),
                     bias = random_floats(size_t(cout), 5);
  memory user_src({src_d, dtp::f32, tag::nchw}, eng, x.data()), user_wei({wei_d, dtp::f32, tag::oihw}, eng, wt.data());
  memory src(pd.src_desc(), eng), wei(pd.weights_desc(), eng), dst(pd.dst_desc(), eng), bmem(bias_md, eng, bias.data());
  reorder(user_src, src).execute(s, user_src, src);
  reorder(user_wei, wei).execute(s, user_wei, wei);
  s.wait();
  convolution_forward conv(pd);
  for (auto _ : state) {
    conv.execute(s, {{DNNL_ARG_SRC, src}, {DNNL_ARG_WEIGHTS, wei}, {DNNL_ARG_BIAS, bmem}, {DNNL_ARG_DST, dst}});
    s.wait();
  }
  set_flops(state, 2.0 * n * cout * h * w * cin * 9);
  state.SetLabel(std::string(winograd ? "winograd " : blocked ? "blocked " : "nchw ") + pd.impl_info_str());
}
#endif

void conv_shapes(benchmark::internal::Benchmark* b, int64_t last_lo, int64_t last_hi) {
  const int64_t shapes[][5] = {{16, 320, 320, 32, 32}, {1, 128, 128, 256, 256}, {2, 128, 128, 256, 256}};
  for (const auto& s : shapes)
    for (int64_t v = last_lo; v <= last_hi; ++v) b->Args({s[0], s[1], s[2], s[3], s[4], v});
  b->ArgNames({"n", "cin", "cout", "h", "w", "v"})->UseRealTime()->Unit(benchmark::kMillisecond);
}

BENCHMARK(BM_egopd_gemm)->Apply([](auto* b) { gemm_shapes(b, true); });
#if EGOPD_BENCH_OPENBLAS
BENCHMARK(BM_openblas_sgemm)->Apply([](auto* b) { gemm_shapes(b, false); });
#endif
BENCHMARK(BM_egopd_conv3x3)->Apply([](auto* b) { conv_shapes(b, 0, 1); });
#if EGOPD_BENCH_ONEDNN
BENCHMARK(BM_onednn_conv3x3)->Apply([](auto* b) { conv_shapes(b, 0, 2); });
#endif
// Temporal shapes: the first `count` of the U-Net's and the VAE decoder's layers, 16 frames.
void temporal_shapes(benchmark::internal::Benchmark* b, size_t count) {
  static const std::vector<int64_t> shapes[] = {
      {1, 16, 320, 320, 1024},    // U-Net 32x32
      {1, 16, 640, 640, 256},     // U-Net 16x16
      {1, 16, 1280, 1280, 64},    // U-Net 8x8
      {1, 16, 1280, 1280, 16},    // U-Net 4x4
      {1, 16, 512, 512, 1024},    // VAE decoder 32x32
      {1, 16, 128, 128, 2048},    // VAE decoder 256x256, in the pixel tiles its temporal blocks run
      {1, 16, 256, 256, 16384},   // VAE decoder 128x128
      {1, 16, 128, 128, 65536},   // VAE decoder 256x256
      {1, 16, 512, 512, 512}};
  for (size_t i = 0; i < std::min(count, std::size(shapes)); ++i) b->Args(shapes[i]);
  b->ArgNames({"b", "f", "cin", "cout", "hw"})->UseRealTime()->Unit(benchmark::kMillisecond);
}

BENCHMARK(BM_egopd_conv_temporal3)->Apply([](auto* b) { temporal_shapes(b, 9); });
BENCHMARK(BM_egopd_conv_temporal3_bf16)->Apply([](auto* b) { temporal_shapes(b, 3); });
BENCHMARK(BM_egopd_conv_temporal3_int8)->Apply([](auto* b) { temporal_shapes(b, 6); });

}  // namespace

int main(int argc, char** argv) {
#if EGOPD_BENCH_ONEDNN
  // oneDNN runs at the instruction set of egopd's kernel path: capped at AVX2 when egopd runs its avx2 path
  // (EGOPD_KERNELS=avx2, or a CPU without AVX-512), its own best otherwise. EGOPD_BENCH_ONEDNN_ISA=avx2|native
  // overrides that.
  const char* isa = std::getenv("EGOPD_BENCH_ONEDNN_ISA");
  const std::string want = isa ? isa : egopd::kernel_path() == egopd::KernelPath::Avx512 ? "native" : "avx2";
  if (want != "native" && want != "avx2") {
    std::fprintf(stderr, "kernels_bench: EGOPD_BENCH_ONEDNN_ISA must be avx2 or native, not '%s'\n", want.c_str());
    return 1;
  }
  if (want == "avx2") dnnl::set_max_cpu_isa(dnnl::cpu_isa::avx2);
  std::fprintf(stderr, "kernels_bench: egopd kernels %s, oneDNN ISA %s\n",
               egopd::kernel_path_name(egopd::kernel_path()), want.c_str());
#endif
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
