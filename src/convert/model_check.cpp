#include "convert/model_check.h"

#include <set>

#include "convert/tensor_io.h"

namespace egopd {
namespace {

bool ends_with(const std::string& s, const std::string& t) {
  return s.size() >= t.size() && s.compare(s.size() - t.size(), t.size(), t) == 0;
}

}  // namespace

std::string join_limited(const std::vector<std::string>& items, size_t max_items) {
  std::string s;
  for (size_t i = 0; i < items.size() && i < max_items; ++i) s += (i ? ", " : "") + items[i];
  if (items.size() > max_items) s += " (+" + std::to_string(items.size() - max_items) + " more)";
  return s;
}

std::string KeyCheck::summary(const std::string& label) const {
  std::string s = label + ":";
  auto part = [&](const std::vector<std::string>& v, const char* what) {
    if (v.empty()) return;
    if (s.back() != ':') s += ";";
    s += ' ';  // (appended, not " " + string: GCC 12 warns -Wstringop-overflow falsely on that form)
    s += std::to_string(v.size()) + " " + what + " (" + join_limited(v, 8) + ")";
  };
  part(missing, "missing");
  part(wrong_shape, "with the wrong shape");
  part(unexpected, "unexpected");
  part(wrong_dtype, "of a type the runtime cannot use as a weight");
  if (ok()) s += " ok";
  return s;
}

bool tolerated_extra(const std::string& folder, const std::string& key, const std::map<std::string, StoredInfo>& stored,
                     bool pifr_enabled) {
  if (ends_with(key, ".position_ids") || key == "logit_scale") return true;
  // The other tower's projection of a full CLIPModel file; a text file's own projection (CLIPTextModelWithProjection)
  // is loaded by the runtime when present.
  if (folder == "text_encoder" && (key == "visual_projection.weight" || key == "text_projection.weight")) return true;
  if (folder == "image_encoder" && key == "text_projection.weight") return true;
  if (folder == "unet" && !pifr_enabled && key.find(".pifr.") != std::string::npos) return true;
  if (ends_with(key, "_scale")) {
    auto it = stored.find(key.substr(0, key.size() - 6));
    if (it != stored.end() && it->second.dtype == DType::I8) return true;
  }
  return false;
}

KeyCheck check_keys(const std::string& folder, const std::vector<std::pair<std::string, Shape>>& expected,
                    const std::map<std::string, StoredInfo>& stored, bool pifr_enabled) {
  KeyCheck c;
  std::set<std::string> wanted;
  for (const auto& [key, shape] : expected) {
    wanted.insert(key);
    auto it = stored.find(key);
    if (it == stored.end()) {
      c.missing.push_back(key + " " + shape.str());
    } else if (it->second.shape != shape.vec()) {
      c.wrong_shape.push_back(key + " has " + shape_string(it->second.shape) + ", expected " + shape.str());
    } else if (!is_float_weight(it->second.dtype)) {
      const auto scale = stored.find(key + "_scale");
      const bool q8 = it->second.dtype == DType::I8 && scale != stored.end() && scale->second.dtype == DType::F32;
      if (!q8) c.wrong_dtype.push_back(key + " is " + dtype_name(it->second.dtype));
    }
  }
  for (const auto& [key, info] : stored)
    if (!wanted.count(key) && !tolerated_extra(folder, key, stored, pifr_enabled)) c.unexpected.push_back(key);
  return c;
}

}  // namespace egopd
