// Instruction-rate ceilings of the GEMM micro-kernels: each loop is the inner loop of one micro-kernel (its loads,
// broadcasts and multiply-adds, operands in L1), one thread, no packing, no stores. It answers "how much faster can
// int8 or bf16 be than float32 on this core at most" before any blocking is involved: e.g. the AVX2 int8 kernel's
// vpmaddubsw + vpmaddwd + vpaddd against the AVX2 float32 kernel's FMAs. Counter GMAC/s: multiply-adds per second.
// Loops for instructions the CPU lacks are skipped with a message.
#include <benchmark/benchmark.h>

#include <cstdint>

#include "core/cpu.h"

namespace {

#if defined(__x86_64__)

// Zeros: the A stream (up to 12 KiB per 256 steps) and the B stream (up to 32 KiB), 48 KiB together: in L1 or L2.
alignas(64) int32_t g_operands[12288];

// Runs `steps` k steps of one loop per call of `body` (256 steps per call) and sets GMAC/s.
template <class Body>
void run_loop(benchmark::State& state, bool supported, const char* needs, double macs_per_step, Body body) {
  if (!supported) {
    state.SkipWithError(needs);
    return;
  }
  for (auto _ : state) body(g_operands, g_operands + 4096);
  state.counters["GMAC/s"] = benchmark::Counter(macs_per_step * 256.0 * double(state.iterations()) * 1e-9,
                                                benchmark::Counter::kIsRate);
}

#define EGOPD_CLOBBER_YMM                                                                                        \
  "cc", "memory", "xmm0", "xmm1", "xmm2", "xmm3", "xmm4", "xmm5", "xmm6", "xmm7", "xmm8", "xmm9", "xmm10", "xmm11", \
      "xmm12", "xmm13", "xmm14", "xmm15"

// 256 steps of a 16-column ymm tile: `load` the two B vectors, then ROWS (the rows' instructions); A advances
// a_step bytes per step.
#define Y_LOOP(load, ROWS, a_step)                                                                                   \
  int64_t k = 256;                                                                                             \
  asm volatile("1:\n\t"                                                                                        \
               load " (%[b]), %%ymm12\n\t" load " 32(%[b]), %%ymm13\n\t" ROWS "add $" #a_step ", %[a]\n\t"           \
               "add $64, %[b]\n\t"                                                                             \
               "dec %[k]\n\t"                                                                                  \
               "jnz 1b"                                                                                        \
               : [a] "+r"(a), [b] "+r"(b), [k] "+r"(k)                                                         \
               :                                                                                               \
               : EGOPD_CLOBBER_YMM);

// The rows of a tile, ROW(i, first accumulator, second accumulator) each.
#define ROWS5(ROW) ROW(0, 0, 1) ROW(1, 2, 3) ROW(2, 4, 5) ROW(3, 6, 7) ROW(4, 8, 9)
#define ROWS6(ROW) ROWS5(ROW) ROW(5, 10, 11)

// AVX2 float32, 6 x 16 tile (avx2/gemm.cpp): per k, 2 B loads, 6 broadcasts, 12 FMAs of 8 lanes.
#define FMA_ROW(i, c0, c1)                                  \
  "vbroadcastss " #i "*4(%[a]), %%ymm14\n\t"                \
  "vfmadd231ps %%ymm12, %%ymm14, %%ymm" #c0 "\n\t"          \
  "vfmadd231ps %%ymm13, %%ymm14, %%ymm" #c1 "\n\t"
__attribute__((target("avx2,fma"))) void fma_6x16(const int32_t* a, const int32_t* b) {
  Y_LOOP("vmovups", ROWS6(FMA_ROW), 24)
}

// AVX2 int8 on int16 pairs (exact for 8-bit operands; the AVX2 kernel before vpmaddubsw), 6 x 16 tile: per pair of
// k, 2 B loads, 6 broadcasts, 12 vpmaddwd + 12 vpaddd.
#define MADD_ROW(i, c0, c1)                               \
  "vpbroadcastd " #i "*4(%[a]), %%ymm14\n\t"              \
  "vpmaddwd %%ymm12, %%ymm14, %%ymm15\n\t"                \
  "vpaddd %%ymm15, %%ymm" #c0 ", %%ymm" #c0 "\n\t"        \
  "vpmaddwd %%ymm13, %%ymm14, %%ymm15\n\t"                \
  "vpaddd %%ymm15, %%ymm" #c1 ", %%ymm" #c1 "\n\t"
__attribute__((target("avx2"))) void vpmaddwd_6x16(const int32_t* a, const int32_t* b) {
  Y_LOOP("vmovdqu", ROWS6(MADD_ROW), 24)
}

// u8 x s8 vpmaddubsw widened by vpmaddwd with `ones`, per 4 k. Its int16 pair sums saturate for two operands of
// -127..127; exact with B within -63..63. 5 x 16 with the ones in a register (ymm11); 6 x 16, the AVX2 int8
// kernel's loop (avx2/gemm.cpp), with them from memory (all 16 registers hold accumulators, B, the broadcast and a
// product).
#define UBS_ROW_WITH(ones, i, c0, c1)                    \
  "vpbroadcastd " #i "*4(%[a]), %%ymm14\n\t"             \
  "vpmaddubsw %%ymm12, %%ymm14, %%ymm15\n\t"             \
  "vpmaddwd " ones ", %%ymm15, %%ymm15\n\t"              \
  "vpaddd %%ymm15, %%ymm" #c0 ", %%ymm" #c0 "\n\t"       \
  "vpmaddubsw %%ymm13, %%ymm14, %%ymm15\n\t"             \
  "vpmaddwd " ones ", %%ymm15, %%ymm15\n\t"              \
  "vpaddd %%ymm15, %%ymm" #c1 ", %%ymm" #c1 "\n\t"
#define UBS_ROW(i, c0, c1) UBS_ROW_WITH("%%ymm11", i, c0, c1)
#define UBS_MEM_ROW(i, c0, c1) UBS_ROW_WITH("%[ones]", i, c0, c1)
__attribute__((target("avx2"))) void vpmaddubsw_5x16(const int32_t* a, const int32_t* b) {
  Y_LOOP("vmovdqu", ROWS5(UBS_ROW), 20)
}

alignas(32) const int16_t g_ones16[16] = {1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1};
__attribute__((target("avx2"))) void vpmaddubsw_6x16(const int32_t* a, const int32_t* b) {
  int64_t k = 256;
  asm volatile("1:\n\t"
               "vmovdqu (%[b]), %%ymm12\n\t"
               "vmovdqu 32(%[b]), %%ymm13\n\t" ROWS6(UBS_MEM_ROW) "add $24, %[a]\n\t"
               "add $64, %[b]\n\t"
               "dec %[k]\n\t"
               "jnz 1b"
               : [a] "+r"(a), [b] "+r"(b), [k] "+r"(k)
               : [ones] "m"(g_ones16)
               : EGOPD_CLOBBER_YMM);
}

#define EGOPD_CLOBBER_ZMM                                                                                         \
  "cc", "memory", "xmm0", "xmm1", "xmm2", "xmm3", "xmm4", "xmm5", "xmm6", "xmm7", "xmm8", "xmm9", "xmm10", "xmm11",  \
      "xmm12", "xmm13", "xmm14", "xmm15", "xmm16", "xmm17", "xmm18", "xmm19", "xmm20", "xmm21", "xmm22", "xmm23", \
      "xmm24", "xmm25", "xmm26", "xmm27"

// AVX-512, 12 x 32 tile (avx512/gemm.cpp): per k step, 2 B loads, 12 broadcasts, 24 multiply-adds (`op`: vfmadd231ps
// on floats, vpdpbusd on 4 int8 pairs of k, vdpbf16ps on 2 bfloat16 pairs), each with its micro-kernel's broadcast
// (`bcast`: vbroadcastss for floats, vpbroadcastd for the 32-bit slots of pairs and quads; feeding the float FMAs from
// vpbroadcastd ran 9% slower on an AMD EPYC Zen 5 class core: 102 against 112 GMAC/s).
#define Z_ROW(bcast, op, i, c0, c1)                                \
  bcast " " #i "*4(%[a]), %%zmm26\n\t"                              \
  op " %%zmm24, %%zmm26, %%zmm" #c0 "\n\t"                         \
  op " %%zmm25, %%zmm26, %%zmm" #c1 "\n\t"
#define Z_ROWS(bcast, op)                                                                                      \
  Z_ROW(bcast, op, 0, 0, 1) Z_ROW(bcast, op, 1, 2, 3) Z_ROW(bcast, op, 2, 4, 5) Z_ROW(bcast, op, 3, 6, 7)          \
  Z_ROW(bcast, op, 4, 8, 9) Z_ROW(bcast, op, 5, 10, 11) Z_ROW(bcast, op, 6, 12, 13) Z_ROW(bcast, op, 7, 14, 15)   \
  Z_ROW(bcast, op, 8, 16, 17) Z_ROW(bcast, op, 9, 18, 19) Z_ROW(bcast, op, 10, 20, 21) Z_ROW(bcast, op, 11, 22, 23)
#define Z_LOOP(load, bcast, op)                                                                                 \
  int64_t k = 256;                                                                                              \
  asm volatile("1:\n\t"                                                                                         \
               load " (%[b]), %%zmm24\n\t"                                                                     \
               load " 64(%[b]), %%zmm25\n\t" Z_ROWS(bcast, op) "add $48, %[a]\n\t"                             \
               "add $128, %[b]\n\t"                                                                             \
               "dec %[k]\n\t"                                                                                   \
               "jnz 1b"                                                                                         \
               : [a] "+r"(a), [b] "+r"(b), [k] "+r"(k)                                                          \
               :                                                                                                \
               : EGOPD_CLOBBER_ZMM);
__attribute__((target("avx512f"))) void fma_12x32(const int32_t* a, const int32_t* b) {
  Z_LOOP("vmovups", "vbroadcastss", "vfmadd231ps")
}
__attribute__((target("avx512f,avx512vnni"))) void vpdpbusd_12x32(const int32_t* a, const int32_t* b) {
  Z_LOOP("vmovdqu32", "vpbroadcastd", "vpdpbusd")
}
__attribute__((target("avx512f,avx512bf16"))) void vdpbf16ps_12x32(const int32_t* a, const int32_t* b) {
  Z_LOOP("vmovups", "vpbroadcastd", "vdpbf16ps")
}

const egopd::CpuInfo& cpu() { return egopd::cpu_info(); }

void BM_avx2_fma_6x16(benchmark::State& s) { run_loop(s, cpu().avx2_fma_f16c, "needs AVX2+FMA", 96, fma_6x16); }
void BM_avx2_vpmaddwd_6x16(benchmark::State& s) { run_loop(s, cpu().avx2_fma_f16c, "needs AVX2", 192, vpmaddwd_6x16); }
void BM_avx2_vpmaddubsw_5x16(benchmark::State& s) {
  run_loop(s, cpu().avx2_fma_f16c, "needs AVX2", 320, vpmaddubsw_5x16);
}
void BM_avx2_vpmaddubsw_6x16(benchmark::State& s) {
  run_loop(s, cpu().avx2_fma_f16c, "needs AVX2", 384, vpmaddubsw_6x16);
}
void BM_avx512_fma_12x32(benchmark::State& s) { run_loop(s, cpu().avx512, "needs AVX-512", 384, fma_12x32); }
void BM_avx512_vpdpbusd_12x32(benchmark::State& s) {
  run_loop(s, cpu().avx512 && cpu().avx512_vnni, "needs AVX512-VNNI", 1536, vpdpbusd_12x32);
}
void BM_avx512_vdpbf16ps_12x32(benchmark::State& s) {
  run_loop(s, cpu().avx512 && cpu().avx512_bf16, "needs AVX512-BF16", 768, vdpbf16ps_12x32);
}
BENCHMARK(BM_avx2_fma_6x16);
BENCHMARK(BM_avx2_vpmaddwd_6x16);
BENCHMARK(BM_avx2_vpmaddubsw_5x16);
BENCHMARK(BM_avx2_vpmaddubsw_6x16);
BENCHMARK(BM_avx512_fma_12x32);
BENCHMARK(BM_avx512_vpdpbusd_12x32);
BENCHMARK(BM_avx512_vdpbf16ps_12x32);

#endif  // __x86_64__

}  // namespace

BENCHMARK_MAIN();
