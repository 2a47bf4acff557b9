// How the tests judge whether memory stays flat over many runs in one process (the batch runner's clips, the C
// API's predictions): by the heap in use, and by the resident set's floor. The resident set swings by megabytes
// from one run to the next with the tests running in parallel (measured: -5.6 / +3.5 / +2.1 MB as the allocator
// returns and takes back large blocks) and takes one-time steps (+0.5-1.5 MB, another malloc arena for an OpenMP
// thread), so neither its value after one run nor its median step measures a leak; its lowest value over ten runs
// does, compared between an early and a late window.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace egopd::testing_memory {

// Lowest resident set over runs [late, late + 10) minus the lowest over [early, early + 10).
inline int64_t rss_floor_growth(const std::vector<int64_t>& rss_after_run, size_t early, size_t late) {
  const auto floor_of = [&](size_t first) {
    return *std::min_element(rss_after_run.begin() + std::ptrdiff_t(first),
                             rss_after_run.begin() + std::ptrdiff_t(first + 10));
  };
  return floor_of(late) - floor_of(early);
}

// " s1 s2 ...": each run's step from `from` on (one step or a steady climb: says which kind a failure is).
inline std::string steps_from(const std::vector<int64_t>& values, size_t from) {
  std::string each;
  for (size_t i = std::max<size_t>(from, 1); i < values.size(); ++i) {
    each += ' ';
    each += std::to_string(values[i] - values[i - 1]);
  }
  return each;
}

}  // namespace egopd::testing_memory
