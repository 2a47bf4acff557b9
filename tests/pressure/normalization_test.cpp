// Normalisation, stabilisation and log bins against hand-computed values (pressure.md §1-§3).
#include <gtest/gtest.h>

#include <vector>

#include "core/error.h"
#include "pressure/normalization.h"

namespace egopd {
namespace {

// 30 segment taxels (6 per finger, ids 0..29 in finger order) plus two palm taxels (30, 31).
HandTemplate segment_template() {
  const Region segs[] = {Region::SegThumb, Region::SegIndex, Region::SegMiddle, Region::SegRing, Region::SegLittle};
  std::vector<Sensor> s;
  for (int k = 0; k < 5; ++k)
    for (int j = 0; j < 6; ++j) s.push_back({int(s.size()), {double(k), double(j)}, segs[k]});
  s.push_back({30, {0, 10}, Region::Palm});
  s.push_back({31, {1, 10}, Region::Palm});
  return HandTemplate::from_parts("seg", s, {{0, 0}, {10, 0}, {10, 12}}, true);
}

TEST(Normalization, Thresholds) {
  EXPECT_EQ(kContactTau, 0.025);
  EXPECT_EQ(normalize_reading(0), 0);
  EXPECT_EQ(normalize_reading(4.999), 0);
  EXPECT_EQ(normalize_reading(5), 0.025);
  EXPECT_EQ(normalize_reading(100), 0.5);
  EXPECT_EQ(normalize_reading(200), 1.0);
  EXPECT_EQ(normalize_reading(350), 1.0);
  EXPECT_FALSE(in_contact(0.025));  // strict
  EXPECT_TRUE(in_contact(0.0250001));
}

TEST(Stabilization, GroupMeansThenThreshold) {
  const HandTemplate t = segment_template();
  std::vector<double> r(32, 0.0);
  for (int j = 0; j < 6; ++j) r[j] = j + 1;  // thumb: 1..6 -> mean 3.5
  r[11] = 30;                               // index: one taxel at 30 -> mean 5
  for (int j = 12; j < 18; ++j) r[j] = 4;   // middle: all 4 -> stays 4 (below p_min)
  r[30] = 7;
  r[31] = 3;
  stabilize_row(t, r.data());
  for (int j = 0; j < 6; ++j) EXPECT_DOUBLE_EQ(r[j], 3.5);
  for (int j = 6; j < 12; ++j) EXPECT_DOUBLE_EQ(r[j], 5.0);
  for (int j = 12; j < 18; ++j) EXPECT_DOUBLE_EQ(r[j], 4.0);
  EXPECT_EQ(r[30], 7);  // not in a group: unchanged
  EXPECT_EQ(r[31], 3);
  // Order matters: after stabilisation the index group sits exactly at p_min (normalised τ, not in contact);
  // normalising first would have kept the single 30 N taxel (0.15) and zeroed the rest.
  EXPECT_EQ(normalize_reading(r[6]), 0.025);
  EXPECT_EQ(normalize_reading(r[0]), 0.0);
}

TEST(Stabilization, IdempotentBitExact) {
  const HandTemplate t = segment_template();
  std::vector<double> r(32);
  for (int m = 0; m < 32; ++m) r[m] = 0.1 * (m % 7) + 0.3;
  stabilize_row(t, r.data());
  const std::vector<double> once = r;
  stabilize_row(t, r.data());
  EXPECT_EQ(r, once);
}

TEST(LogBins, SpecTables) {
  EXPECT_EQ(LogBins(9, 0, 200).edges(), (std::vector<double>{0, 1, 2, 5, 10, 18, 33, 61, 111, 200}));
  EXPECT_EQ(LogBins(9, 0, 350).edges(), (std::vector<double>{0, 1, 3, 6, 13, 25, 49, 94, 182, 350}));
}

TEST(LogBins, LabelsAndCentres) {
  const LogBins b(9, 0, 200);
  EXPECT_EQ(b.label(0), 1);
  EXPECT_EQ(b.label(0.99), 1);
  EXPECT_EQ(b.label(1), 2);
  EXPECT_EQ(b.label(4.9), 3);
  EXPECT_EQ(b.label(110.9), 8);
  EXPECT_EQ(b.label(111), 9);
  EXPECT_EQ(b.label(200), 9);   // last bin includes v_max
  EXPECT_EQ(b.label(500), 9);   // clipped
  EXPECT_EQ(b.label(-1), 1);    // clipped into the first bin
  EXPECT_EQ(b.centre(1), 0.5);
  EXPECT_EQ(b.centre(9), 155.5);
  EXPECT_THROW(b.centre(0), Error);
}

TEST(LogBins, SmallRanges) {
  EXPECT_EQ(LogBins(2, 0, 8).edges(), (std::vector<double>{0, 2, 8}));  // b_1 = sqrt(9) - 1
  EXPECT_EQ(LogBins(1, 3, 7).edges(), (std::vector<double>{3, 7}));
  EXPECT_THROW(LogBins(0, 0, 200), Error);
  EXPECT_THROW(LogBins(9, 10, 10), Error);
}

}  // namespace
}  // namespace egopd
