#include "pressure/taxel_csv.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string_view>
#include <unordered_set>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/safetensors.h"

namespace egopd {
namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> out;
  size_t start = 0;
  for (;;) {
    const size_t c = line.find(',', start);
    out.push_back(trim(line.substr(start, c == std::string_view::npos ? std::string_view::npos : c - start)));
    if (c == std::string_view::npos) return out;
    start = c + 1;
  }
}

std::string quoted(std::string_view s) { return std::string("'").append(s.substr(0, 40)).append("'"); }

}  // namespace

void TaxelSequence::add_row(int64_t frame, const double* v) {
  frames.push_back(frame);
  values.insert(values.end(), v, v + num_taxels);
}

TaxelSequence parse_taxel_csv(const std::string& text, const std::string& source) {
  TaxelSequence s;
  std::unordered_set<int64_t> seen;
  std::vector<double> row;
  size_t pos = 0;
  int line_no = 0;
  bool have_header = false;
  while (pos < text.size()) {
    size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    const std::string_view line = trim(std::string_view(text).substr(pos, end - pos));
    pos = end + 1;
    ++line_no;
    if (line.empty()) continue;
    const std::string at = source + ":" + std::to_string(line_no);
    const auto cells = split(line);
    if (!have_header) {
      if (cells.size() < 2 || cells[0] != "frame")
        throw Error(at + ": header must be 'frame,p0,p1,...' (got " + quoted(line) + ")");
      for (size_t c = 1; c < cells.size(); ++c)
        if (cells[c] != std::string("p").append(std::to_string(c - 1)))
          throw Error(at + ", column " + std::to_string(c + 1) + ": header expected 'p" + std::to_string(c - 1) +
                      "', got " + quoted(cells[c]));
      s.num_taxels = int(cells.size() - 1);
      row.resize(s.num_taxels);
      have_header = true;
      continue;
    }
    if (int(cells.size()) != s.num_taxels + 1)
      throw Error(at + ": expected " + std::to_string(s.num_taxels + 1) + " columns (frame + " +
                  std::to_string(s.num_taxels) + " taxels), got " + std::to_string(cells.size()));
    int64_t frame = 0;
    {
      const auto c = cells[0];
      const auto r = std::from_chars(c.data(), c.data() + c.size(), frame);
      if (c.empty() || r.ec != std::errc() || r.ptr != c.data() + c.size() || frame < 0)
        throw Error(at + ", column 1 (frame): " + quoted(c) + " is not a non-negative integer");
      if (!seen.insert(frame).second) throw Error(at + ", column 1 (frame): duplicate frame " + std::to_string(frame));
    }
    for (int m = 0; m < s.num_taxels; ++m) {
      const auto c = cells[m + 1];
      const std::string col = ", column " + std::to_string(m + 2) + " (p" + std::to_string(m) + "): ";
      double v = 0;
      const auto r = std::from_chars(c.data(), c.data() + c.size(), v);
      if (c.empty() || r.ec != std::errc() || r.ptr != c.data() + c.size() || !std::isfinite(v))
        throw Error(at + col + quoted(c) + " is not a finite number");
      if (v < 0) throw Error(at + col + "negative pressure " + std::string(c));
      row[m] = v;
    }
    s.add_row(frame, row.data());
  }
  if (!have_header) throw Error(source + ": empty file (expected header 'frame,p0,p1,...')");
  return s;
}

TaxelSequence read_taxel_csv(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path + ": cannot open taxel CSV file");
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_taxel_csv(ss.str(), path);
}

std::string format_taxel_csv(const TaxelSequence& s) {
  std::string out = "frame";
  for (int m = 0; m < s.num_taxels; ++m) out += ",p" + std::to_string(m);
  out += '\n';
  char buf[64];
  for (int64_t t = 0; t < s.num_frames(); ++t) {
    out += std::to_string(s.frames[t]);
    for (int m = 0; m < s.num_taxels; ++m) {
      const auto r = std::to_chars(buf, buf + sizeof buf, s.row(t)[m]);
      out += ',';
      out.append(buf, r.ptr);
    }
    out += '\n';
  }
  return out;
}

void write_taxel_csv(const std::string& path, const TaxelSequence& s) { write_file_atomic(path, format_taxel_csv(s)); }

}  // namespace egopd
