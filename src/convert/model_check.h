#pragma once
// Comparing a component's stored tensors with the exact parameter list its model class requests (weights.md §3.1):
// missing keys, wrong shapes, and extra keys other than the tolerated ones.
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "core/dtype.h"
#include "core/tensor.h"

namespace egopd {

struct StoredInfo {
  DType dtype = DType::F32;
  std::vector<int64_t> shape;
};

struct KeyCheck {
  std::vector<std::string> missing;      // "key [shape]"
  std::vector<std::string> wrong_shape;  // "key has [a], expected [b]"
  std::vector<std::string> unexpected;   // "key"
  std::vector<std::string> wrong_dtype;  // "key is I32" (not F32/F16/BF16, nor I8 with its F32 _scale)
  bool ok() const { return missing.empty() && wrong_shape.empty() && unexpected.empty() && wrong_dtype.empty(); }
  size_t problems() const { return missing.size() + wrong_shape.size() + unexpected.size() + wrong_dtype.size(); }
  // "unet: 2 missing (a [3], b [4]); 1 unexpected (c)" — one line, long lists shortened.
  std::string summary(const std::string& label) const;
};

// Extra tensors the runtime ignores (weights.md §3.1): *.position_ids, logit_scale, the other tower's projection,
// pifr.* when PIFR is disabled, and the <key>_scale companion of an I8 <key>.
bool tolerated_extra(const std::string& folder, const std::string& key, const std::map<std::string, StoredInfo>& stored,
                     bool pifr_enabled);

KeyCheck check_keys(const std::string& folder, const std::vector<std::pair<std::string, Shape>>& expected,
                    const std::map<std::string, StoredInfo>& stored, bool pifr_enabled);

// "a, b, c (+5 more)"
std::string join_limited(const std::vector<std::string>& items, size_t max_items);

}  // namespace egopd
