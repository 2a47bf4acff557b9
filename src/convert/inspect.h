#pragma once
// `egopd-convert inspect`: tensors (name, dtype, shape, bytes), configs and totals of a weight file or a model
// directory, and for every component the check of its keys and shapes against the model class built from its config.
#include <ostream>
#include <string>

namespace egopd {

struct InspectOptions {
  bool list_tensors = true;
};

// Prints the report; returns the number of problems found (0 = the directory loads as configured).
size_t inspect_path(const std::string& path, std::ostream& out, const InspectOptions& options);

}  // namespace egopd
