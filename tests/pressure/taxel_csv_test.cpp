// Taxel CSV reading/writing and its one-line errors (file, line, column).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "core/error.h"
#include "pressure/taxel_csv.h"

namespace egopd {
namespace {

std::string error_of(const std::string& text) {
  try {
    parse_taxel_csv(text, "x.csv");
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(TaxelCsv, ParsesRowsWithCrlfAndBlankLines) {
  const TaxelSequence s = parse_taxel_csv("frame,p0,p1,p2\r\n0,1.5,0,200\r\n\r\n3, 7 ,1e2,0.25\r\n", "x.csv");
  EXPECT_EQ(s.num_taxels, 3);
  EXPECT_EQ(s.frames, (std::vector<int64_t>{0, 3}));
  EXPECT_EQ(s.values, (std::vector<double>{1.5, 0, 200, 7, 100, 0.25}));
  EXPECT_EQ(parse_taxel_csv("frame,p0\n", "x.csv").num_frames(), 0);
}

TEST(TaxelCsv, WriteReadRoundTripIsExact) {
  TaxelSequence s;
  s.num_taxels = 162;
  std::vector<double> row(162);
  for (int t = 0; t < 3; ++t) {
    for (int m = 0; m < 162; ++m) row[m] = 200.0 * (m * 0.0123456789 + t / 3.0) / 7.0;
    s.add_row(10 + t, row.data());
  }
  const std::string text = format_taxel_csv(s);
  EXPECT_EQ(text.substr(0, 15), "frame,p0,p1,p2,");
  EXPECT_NE(text.find(",p161\n"), std::string::npos);
  const std::string path = ::testing::TempDir() + "/egopd_taxel_roundtrip.csv";
  write_taxel_csv(path, s);
  const TaxelSequence r = read_taxel_csv(path);
  EXPECT_EQ(r.frames, s.frames);
  EXPECT_EQ(r.values, s.values);  // shortest round-trip formatting loses nothing
  std::filesystem::remove(path);
}

TEST(TaxelCsv, MissingFile) {
  try {
    read_taxel_csv("/nonexistent/pred.csv");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "/nonexistent/pred.csv: cannot open taxel CSV file");
  }
}

TEST(TaxelCsv, ErrorsNameLineAndColumn) {
  EXPECT_EQ(error_of("frame,p0,p1\n0,1,2\n1,3\n"), "x.csv:3: expected 3 columns (frame + 2 taxels), got 2");
  EXPECT_EQ(error_of("frame,p0,p1\n0,1,2,4\n"), "x.csv:2: expected 3 columns (frame + 2 taxels), got 4");
  EXPECT_EQ(error_of("frame,p0,p1\n0,1,abc\n"), "x.csv:2, column 3 (p1): 'abc' is not a finite number");
  EXPECT_EQ(error_of("frame,p0,p1\n0,,1\n"), "x.csv:2, column 2 (p0): '' is not a finite number");
  EXPECT_EQ(error_of("frame,p0,p1\n0,1.5x,1\n"), "x.csv:2, column 2 (p0): '1.5x' is not a finite number");
  EXPECT_EQ(error_of("frame,p0,p1\n0,nan,1\n"), "x.csv:2, column 2 (p0): 'nan' is not a finite number");
  EXPECT_EQ(error_of("frame,p0,p1\n0,1,-2\n"), "x.csv:2, column 3 (p1): negative pressure -2");
  EXPECT_EQ(error_of("frame,p0,p1\nx,1,2\n"), "x.csv:2, column 1 (frame): 'x' is not a non-negative integer");
  EXPECT_EQ(error_of("frame,p0,p1\n1.5,1,2\n"), "x.csv:2, column 1 (frame): '1.5' is not a non-negative integer");
  EXPECT_EQ(error_of("frame,p0,p1\n4,1,2\n4,1,2\n"), "x.csv:3, column 1 (frame): duplicate frame 4");
  EXPECT_EQ(error_of("frame,p0,p2\n"), "x.csv:1, column 3: header expected 'p1', got 'p2'");
  EXPECT_EQ(error_of("time,p0\n"), "x.csv:1: header must be 'frame,p0,p1,...' (got 'time,p0')");
  EXPECT_EQ(error_of(""), "x.csv: empty file (expected header 'frame,p0,p1,...')");
}

}  // namespace
}  // namespace egopd
