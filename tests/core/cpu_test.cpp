// CPU naming: the x86 family, model and core generation from the CPUID leaf 1 signature. The signatures are the
// published ones of each part (EAX of CPUID leaf 1, as `cpuid` and /proc/cpuinfo show them).
#include <gtest/gtest.h>

#include "core/cpu.h"

namespace egopd {
namespace {

TEST(CpuName, AmdGenerationsFromTheirSignatures) {
  EXPECT_EQ(x86_core_name(0x00800F12, true), "family 23 model 1, Zen / Zen+");  // EPYC 7001 (Naples)
  EXPECT_EQ(x86_core_name(0x00830F10, true), "family 23 model 49, Zen 2");      // EPYC 7002 (Rome)
  EXPECT_EQ(x86_core_name(0x00A00F11, true), "family 25 model 1, Zen 3");       // EPYC 7003 (Milan)
  EXPECT_EQ(x86_core_name(0x00A20F12, true), "family 25 model 33, Zen 3");      // Ryzen 5000 (Vermeer)
  EXPECT_EQ(x86_core_name(0x00A10F11, true), "family 25 model 17, Zen 4");      // EPYC 9004 (Genoa)
  EXPECT_EQ(x86_core_name(0x00A60F12, true), "family 25 model 97, Zen 4");      // Ryzen 7000 (Raphael)
  EXPECT_EQ(x86_core_name(0x00AA0F02, true), "family 25 model 160, Zen 4");     // EPYC 97x4 (Bergamo)
  EXPECT_EQ(x86_core_name(0x00B00F21, true), "family 26 model 2, Zen 5");       // EPYC 9005 (Turin)
}

TEST(CpuName, OtherVendorsByNumberOnly) {
  EXPECT_EQ(x86_core_name(0x000806F8, false), "family 6 model 143");  // Xeon 4th gen (Sapphire Rapids)
  EXPECT_EQ(x86_core_name(0x000A0655, false), "family 6 model 165");  // Core 10th gen (Comet Lake-S)
  // The extended model only counts for families 6 and 15: in this made-up family 5 signature bits 16-19 are ignored.
  EXPECT_EQ(x86_core_name(0x00010543, false), "family 5 model 4");
}

TEST(CpuName, DescriptionJoinsTheBrandAndTheCore) {
  CpuInfo ci;
  EXPECT_EQ(ci.description(), "unknown");
  ci.model = "AMD EPYC";
  EXPECT_EQ(ci.description(), "AMD EPYC");
  ci.core = "family 25 model 17, Zen 4";
  EXPECT_EQ(ci.description(), "AMD EPYC (family 25 model 17, Zen 4)");
  ci.model.clear();
  EXPECT_EQ(ci.description(), "family 25 model 17, Zen 4");
}

}  // namespace
}  // namespace egopd
