// The emulated AVX-512 instructions of a -DEGOPD_EMULATE_AVX512=ON build (src/core/kernels/avx512/emulated.h and
// the SIMDe functions the kernels rely on) against the instruction set reference's definitions, on the cases where
// an emulation most easily goes wrong: rounding ties, denormals, NaN, infinities, masks at the edge of mapped
// memory. Expected values are worked out by hand from those definitions.
#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include "core/kernels/avx512/isa.h"

namespace {

uint32_t bits(float x) {
  uint32_t u;
  std::memcpy(&u, &x, 4);
  return u;
}
float from_bits(uint32_t u) {
  float x;
  std::memcpy(&x, &u, 4);
  return x;
}

template <class T, class V>
void store(const V& v, T* out) {
  std::memcpy(out, &v, sizeof(V));
}

TEST(Avx512Emulation, FloatToBf16RoundsTiesToEvenFlushesDenormalsQuietsNaN) {
  const float in[16] = {1.0f, from_bits(0x3f808000u), from_bits(0x3f818000u), from_bits(0x3f808001u),
                        1e-40f, -1e-40f, INFINITY, -INFINITY, from_bits(0x7fa00000u), from_bits(0xffc00001u),
                        std::numeric_limits<float>::max(), -2.0f, 0.0f, -0.0f, from_bits(0x00800000u), 3.0f};
  // 1+2^-8 is a tie: even (down); 1+3*2^-8 a tie: even (up); just above a tie: up. Denormals: signed zero. A
  // signalling NaN comes out quiet; FLT_MAX rounds up to infinity; the smallest normal stays.
  const uint16_t expect[16] = {0x3f80, 0x3f80, 0x3f82, 0x3f81, 0x0000, 0x8000, 0x7f80, 0xff80,
                               0x7fe0, 0xffc0, 0x7f80, 0xc000, 0x0000, 0x8000, 0x0080, 0x4040};
  uint16_t got[16];
  store(_mm512_cvtneps_pbh(_mm512_loadu_ps(in)), got);
  for (int i = 0; i < 16; ++i) EXPECT_EQ(got[i], expect[i]) << "lane " << i;

  // Two registers: the second operand's lanes first.
  uint16_t pair[32];
  store(_mm512_cvtne2ps_pbh(_mm512_set1_ps(2.0f), _mm512_set1_ps(-1.0f)), pair);
  for (int i = 0; i < 16; ++i) EXPECT_EQ(pair[i], 0xbf80) << i;
  for (int i = 16; i < 32; ++i) EXPECT_EQ(pair[i], 0x4000) << i;
}

TEST(Avx512Emulation, RoundscaleModesAndSteps) {
  const float in[16] = {-3.7f, -0.2f, 0.3f, 1.5f, 2.5f, -2.5f, 7.0f, 100.2f,
                        -100.7f, 0.5f, -0.5f, 1e-3f, -1e-3f, 3.0f, INFINITY, -0.0f};
  const float nearest[16] = {-4, -0.0f, 0, 2, 2, -2, 7, 100, -101, 0, -0.0f, 0, -0.0f, 3, INFINITY, -0.0f};
  const float up[16] = {-3, -0.0f, 1, 2, 3, -2, 7, 101, -100, 1, -0.0f, 1, -0.0f, 3, INFINITY, -0.0f};
  const float down[16] = {-4, -1, 0, 1, 2, -3, 7, 100, -101, 0, -1, 0, -1, 3, INFINITY, -0.0f};
  const float quarters_up[16] = {-3.5f, -0.0f, 0.5f, 1.5f, 2.5f, -2.5f, 7, 100.25f,
                                 -100.5f, 0.5f, -0.5f, 0.25f, -0.0f, 3, INFINITY, -0.0f};
  const __m512 x = _mm512_loadu_ps(in);
  float got[16];
  const auto check = [&](const float* expect, const char* what) {
    for (int i = 0; i < 16; ++i) EXPECT_EQ(bits(got[i]), bits(expect[i])) << what << " lane " << i << " x=" << in[i];
  };
  store(_mm512_roundscale_ps(x, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC), got);
  check(nearest, "nearest");
  store(_mm512_roundscale_ps(x, _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC), got);
  check(up, "up");
  store(_mm512_roundscale_ps(x, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC), got);
  check(down, "down");
  store(_mm512_roundscale_ps(x, (2 << 4) | _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC), got);
  check(quarters_up, "quarters up");
}

TEST(Avx512Emulation, ScalefRoundsOnce) {
  // 1.5 * 2^-149 = 3 * 2^-150 lies halfway between 2^-149 and 2^-148: one rounding, to even, gives 2^-148.
  // 1.5 * 2^-150 rounds to 2^-149, although 2^-150 alone would underflow to 0. A denormal a is not flushed
  // (MXCSR.DAZ is off): 2^-130 * 2^20 = 2^-110. b is floored: 2.7 -> 2, -0.5 -> -1.
  const float a[8] = {1.5f, 1.5f, std::ldexp(1.0f, -130), 1.5f, 1.5f, 3.0f, -1.0f, 1.0f};
  const float b[8] = {-149.0f, -150.0f, 20.0f, 2.7f, -0.5f, 130.0f, -INFINITY, INFINITY};
  const float expect[8] = {std::ldexp(1.0f, -148), std::ldexp(1.0f, -149), std::ldexp(1.0f, -110), 6.0f, 0.75f,
                           INFINITY, -0.0f, INFINITY};
  float va[16] = {}, vb[16] = {}, got[16];
  std::memcpy(va, a, sizeof(a));
  std::memcpy(vb, b, sizeof(b));
  store(_mm512_scalef_ps(_mm512_loadu_ps(va), _mm512_loadu_ps(vb)), got);
  for (int i = 0; i < 8; ++i) EXPECT_EQ(bits(got[i]), bits(expect[i])) << "lane " << i;
}

TEST(Avx512Emulation, ConversionsToIntegersRoundToNearestEven) {
  const float in[16] = {2.5f, 3.5f, -2.5f, -3.5f, 0.49999997f, 3e9f, -3e9f, NAN, 1.0f, -1.0f, 0, 0, 0, 0, 0, 0};
  const int32_t expect[16] = {2, 4, -2, -4, 0, INT32_MIN, INT32_MIN, INT32_MIN, 1, -1, 0, 0, 0, 0, 0, 0};
  int32_t got[16];
  store(_mm512_cvtps_epi32(_mm512_loadu_ps(in)), got);
  for (int i = 0; i < 16; ++i) EXPECT_EQ(got[i], expect[i]) << "lane " << i;

  // Widening and narrowing: zero- vs sign-extension, truncation.
  const uint16_t u16[16] = {0, 1, 0x7fff, 0x8000, 0xffff, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
  store(_mm512_cvtepu16_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(u16))), got);
  EXPECT_EQ(got[3], 0x8000);
  EXPECT_EQ(got[4], 0xffff);
  const int8_t s8[16] = {-128, -1, 0, 127, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16};
  store(_mm512_cvtepi8_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(s8))), got);
  EXPECT_EQ(got[0], -128);
  EXPECT_EQ(got[1], -1);
  EXPECT_EQ(got[3], 127);
  int16_t narrow[16];
  store(_mm512_cvtepi32_epi16(_mm512_set1_epi32(0x12348765)), narrow);
  EXPECT_EQ(uint16_t(narrow[7]), 0x8765);
}

TEST(Avx512Emulation, DotProductsOfPairsAndQuads) {
  // vpdpbusd: unsigned bytes of a times signed bytes of b, four per lane, added to the lane.
  const __m512i a = _mm512_set1_epi32(int(0x01ff80c8u));  // bytes 200, 128, 255, 1
  const __m512i b = _mm512_set1_epi32(int(0x7f80fffdu));  // bytes -3, -1, -128, 127
  int32_t q[16];
  store(_mm512_dpbusd_epi32(_mm512_set1_epi32(10), a, b), q);
  EXPECT_EQ(q[0], 10 + 200 * -3 + 128 * -1 + 255 * -128 + 1 * 127);
  // vdpbf16ps: two bfloat16 products per lane (exact in float32), added to the lane.
  const __m512i x = _mm512_set1_epi32(int(0x40403fc0u));  // 1.5, 3
  const __m512i y = _mm512_set1_epi32(int(0xbf804100u));  // 8, -1
  float f[16];
  store(_mm512_dpbf16_ps(_mm512_set1_ps(0.25f), (__m512bh)x, (__m512bh)y), f);
  EXPECT_EQ(f[0], 0.25f + 1.5f * 8.0f + 3.0f * -1.0f);
}

TEST(Avx512Emulation, MaskedLoadsAndStoresTouchOnlyTheirLanes) {
  // A page followed by an inaccessible one: the last 5 floats of the page read and written through masks that
  // select only them (as the kernels' tails do) must not fault.
  const long page = sysconf(_SC_PAGESIZE);
  char* base = static_cast<char*>(mmap(nullptr, 2 * page, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0));
  ASSERT_NE(base, MAP_FAILED);
  ASSERT_EQ(mprotect(base + page, page, PROT_NONE), 0);
  float* tail = reinterpret_cast<float*>(base + page) - 5;
  for (int i = 0; i < 5; ++i) tail[i] = float(i + 1);
  const __mmask16 m = 0x1f;
  float got[16];
  store(_mm512_maskz_loadu_ps(m, tail), got);
  for (int i = 0; i < 16; ++i) EXPECT_EQ(got[i], i < 5 ? float(i + 1) : 0.0f) << i;
  store(_mm512_mask_loadu_ps(_mm512_set1_ps(-7.0f), m, tail), got);
  for (int i = 0; i < 16; ++i) EXPECT_EQ(got[i], i < 5 ? float(i + 1) : -7.0f) << i;
  _mm512_mask_storeu_ps(tail, m, _mm512_set1_ps(9.0f));
  _mm512_mask_storeu_epi32(tail, __mmask16(0x3), _mm512_set1_epi32(0));
  _mm256_mask_storeu_ps(tail, __mmask8(0x1), _mm256_set1_ps(4.0f));
  EXPECT_EQ(tail[0], 4.0f);
  EXPECT_EQ(tail[1], 0.0f);
  EXPECT_EQ(tail[4], 9.0f);
  const int16_t* h = reinterpret_cast<const int16_t*>(base + page) - 3;
  int16_t h16[16];
  store(_mm256_maskz_loadu_epi16(__mmask16(0x7), h), h16);
  EXPECT_EQ(h16[3], 0);
  const int8_t* c = reinterpret_cast<const int8_t*>(base + page) - 2;
  int8_t c8[16];
  store(_mm_maskz_loadu_epi8(__mmask16(0x3), c), c8);
  EXPECT_EQ(c8[2], 0);
  munmap(base, 2 * page);
}

TEST(Avx512Emulation, HalfPrecisionAndHalvesOfRegisters) {
  // F16: 1.0 = 0x3c00, -2.0 = 0xc000, 65504 = 0x7bff, smallest subnormal 2^-24 = 0x0001.
  const uint16_t h[16] = {0x3c00, 0xc000, 0x7bff, 0x0001, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0x3c00};
  float got[16];
  store(_mm512_cvtph_ps(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(h))), got);
  EXPECT_EQ(got[0], 1.0f);
  EXPECT_EQ(got[1], -2.0f);
  EXPECT_EQ(got[2], 65504.0f);
  EXPECT_EQ(got[3], std::ldexp(1.0f, -24));
  EXPECT_EQ(got[15], 1.0f);
  float v[16];
  for (int i = 0; i < 16; ++i) v[i] = float(i);
  float hi[8];
  store(_mm512_extractf32x8_ps(_mm512_loadu_ps(v), 1), hi);
  EXPECT_EQ(hi[0], 8.0f);
  EXPECT_EQ(hi[7], 15.0f);
  double d[8];
  store(_mm512_cvtps_pd(_mm256_loadu_ps(v + 8)), d);
  EXPECT_EQ(d[0], 8.0);
  // 128-bit blocks picked from a and b: imm8 0b01'00'11'10 -> a[2], a[3], b[0], b[1].
  float w[16];
  for (int i = 0; i < 16; ++i) w[i] = float(100 + i);
  store(_mm512_shuffle_f32x4(_mm512_loadu_ps(v), _mm512_loadu_ps(w), 0x4e), got);
  EXPECT_EQ(got[0], 8.0f);
  EXPECT_EQ(got[4], 12.0f);
  EXPECT_EQ(got[8], 100.0f);
  EXPECT_EQ(got[12], 104.0f);
}

}  // namespace
