#pragma once
// Taxel sequences and their CSV files: header `frame,p0,p1,...,p{M-1}`, one row per frame, values in Newtons.
// The reader's errors are one line naming the file, line and column.
#include <cstdint>
#include <string>
#include <vector>

namespace egopd {

struct TaxelSequence {
  int num_taxels = 0;
  std::vector<int64_t> frames;  // frame numbers, one per row
  std::vector<double> values;   // frames.size() × num_taxels, row-major

  int64_t num_frames() const { return int64_t(frames.size()); }
  double* row(int64_t t) { return values.data() + t * num_taxels; }
  const double* row(int64_t t) const { return values.data() + t * num_taxels; }
  void add_row(int64_t frame, const double* v);
};

// Parses CSV text; `source` (usually the path) prefixes errors. Frame numbers must be unique integers >= 0,
// values finite and >= 0 (pressures in Newtons). Blank lines are ignored; CRLF is accepted.
TaxelSequence parse_taxel_csv(const std::string& text, const std::string& source);
TaxelSequence read_taxel_csv(const std::string& path);
// Shortest round-trip decimal for every value; written atomically.
std::string format_taxel_csv(const TaxelSequence& s);
void write_taxel_csv(const std::string& path, const TaxelSequence& s);

}  // namespace egopd
