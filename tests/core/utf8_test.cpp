// UTF-8 validity against the definition (RFC 3629): well-formed sequences pass, every kind of malformed one fails.
#include <gtest/gtest.h>

#include "core/utf8.h"

namespace egopd {
namespace {

TEST(Utf8, WellFormed) {
  for (const char* s : {"", "plain ascii", "caf\xc3\xa9", "\xe2\x82\xac 5", "\xf0\x9f\x96\x90 hand", "\xf4\x8f\xbf\xbf",
                        "\xed\x9f\xbf"})
    EXPECT_TRUE(is_valid_utf8(s)) << s;
}

TEST(Utf8, Malformed) {
  for (const char* s : {"\xff", "\x80", "caf\xc3", "\xc0\xaf", "\xe0\x80\xaf", "\xed\xa0\x80", "\xf4\x90\x80\x80",
                        "\xf8\x88\x80\x80\x80", "\xe2\x82", "ok\xc3\x28"})
    EXPECT_FALSE(is_valid_utf8(s)) << s;
}

}  // namespace
}  // namespace egopd
