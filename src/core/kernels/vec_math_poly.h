#pragma once
// The polynomial coefficients of the SIMD math (avx2/, avx512/ and neon/vec_math.h), kept in one place so every
// kernel path evaluates the same polynomials (highest degree first, for horner()). Chebyshev fits of the exact
// functions; the accuracy is tested against double precision (tests/core/elementwise_test.cpp).
namespace egopd::vmath_poly {

inline constexpr float kExp[5] = {1.392617589e-03f, 8.363173343e-03f, 4.166655615e-02f, 1.666657776e-01f,
                                  5.000000000e-01f};  // (exp(r) - 1 - r) / r^2 on [-ln2/2, ln2/2]
inline constexpr float kErfSmall[7] = {7.875874871e-05f, -8.016864303e-04f, 5.189087242e-03f, -2.685421146e-02f,
                                       1.128359437e-01f, -3.761262596e-01f, 1.128379107e+00f};  // erf(a)/a in a^2, a<1
inline constexpr float kErfcTail[9] = {-4.387202486e-02f, 2.385862917e-01f, -4.306684136e-01f,
                                       2.423289418e-01f,  -1.475901343e-02f, 2.010129243e-01f,
                                       2.430254966e-01f,  2.824241221e-01f,  2.820825875e-01f};  // erfc(a) e^(a^2)/t

}  // namespace egopd::vmath_poly
