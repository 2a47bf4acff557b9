#include "batch/manifest.h"

#include <filesystem>
#include <fstream>
#include <set>

#include "core/error.h"
#include "core/json_text.h"
#include "pipeline/prompt.h"

namespace egopd {
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

bool valid_id(const std::string& id) {
  if (id.empty() || id.size() > 200 || id[0] == '.') return false;
  for (unsigned char c : id)
    if (!(std::isalnum(c) || c == '.' || c == '_' || c == '-')) return false;
  return true;
}

std::string resolve(const fs::path& base, const std::string& p) {
  if (p.empty()) return p;
  const fs::path path(p);
  return path.is_absolute() ? p : (base / path).lexically_normal().string();
}

std::string string_field(const json& j, const char* key, const std::string& where, bool required) {
  if (!j.contains(key) || j[key].is_null()) {
    if (required) throw Error(where + ": field '" + key + "' is required");
    return "";
  }
  if (!j[key].is_string() || j[key].get<std::string>().empty())
    throw Error(where + ": field '" + key + "' must be a non-empty string");
  return j[key].get<std::string>();
}

std::vector<std::string> split_field(const json& j, const std::string& where) {
  if (!j.contains("split") || j["split"].is_null()) return {};
  const json& s = j["split"];
  std::vector<std::string> out;
  if (s.is_string()) out.push_back(s.get<std::string>());
  if (s.is_array())
    for (const json& e : s) {
      if (!e.is_string()) throw Error(where + ": field 'split' must be a string or a list of strings");
      out.push_back(e.get<std::string>());
    }
  if (!s.is_string() && !s.is_array()) throw Error(where + ": field 'split' must be a string or a list of strings");
  for (const std::string& n : out)
    if (!valid_id(n)) throw Error(where + ": split name '" + n + "' must be letters, digits, '.', '_' or '-'");
  return out;
}

ManifestClip parse_clip(const std::string& text, const std::string& where, const fs::path& base) {
  json j;
  try {
    j = parse_json(text);
  } catch (const json::exception&) {
    throw Error(where + ": not a valid JSON object");
  }
  if (!j.is_object()) throw Error(where + ": each line must be a JSON object");
  static const std::set<std::string> known = {"id", "frames", "masks", "meta", "prompt", "gt", "split"};
  for (const auto& item : j.items())
    if (!known.count(item.key()))
      throw Error(where + ": unknown field '" + item.key() + "' (fields: id, frames, masks, meta, prompt, gt, split)");
  ManifestClip c;
  c.id = string_field(j, "id", where, true);
  if (!valid_id(c.id))
    throw Error(where + ": id '" + c.id + "' must be letters, digits, '.', '_' or '-' (it names the output folder)");
  const std::string at = where + " (" + c.id + ")";
  c.frames = resolve(base, string_field(j, "frames", at, true));
  c.masks = resolve(base, string_field(j, "masks", at, false));
  c.gt = resolve(base, string_field(j, "gt", at, false));
  if (j.contains("prompt") && !j["prompt"].is_null()) {
    if (!j["prompt"].is_string()) throw Error(at + ": field 'prompt' must be a string");
    c.prompt = j["prompt"].get<std::string>();
  }
  if (j.contains("meta") && !j["meta"].is_null()) {
    if (c.prompt) throw Error(at + ": give either 'meta' or 'prompt', not both");
    c.meta = prompt_fields_from_json(j["meta"], at + ": meta");
  }
  c.splits = split_field(j, at);
  return c;
}

}  // namespace

Manifest read_manifest(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path + ": cannot open manifest");
  Manifest m;
  m.path = path;
  const fs::path base = fs::absolute(fs::path(path)).parent_path();
  std::set<std::string> ids;
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.find_first_not_of(" \t") == std::string::npos) continue;
    ManifestClip c = parse_clip(line, path + ":" + std::to_string(n), base);
    c.line = n;
    if (!ids.insert(c.id).second) throw Error(path + ":" + std::to_string(n) + ": id '" + c.id + "' appears twice");
    m.clips.push_back(std::move(c));
  }
  if (in.bad()) throw Error(path + ": read error");
  if (m.clips.empty()) throw Error(path + ": manifest lists no clips");
  return m;
}

std::string manifest_line(const ManifestClip& c) {
  nlohmann::ordered_json j;
  j["id"] = c.id;
  j["frames"] = c.frames;
  if (!c.masks.empty()) j["masks"] = c.masks;
  if (c.meta) j["meta"] = *c.meta;
  if (c.prompt) j["prompt"] = *c.prompt;
  if (!c.gt.empty()) j["gt"] = c.gt;
  if (c.splits.size() == 1) j["split"] = c.splits[0];
  if (c.splits.size() > 1) j["split"] = c.splits;
  return dump_json(j);
}

}  // namespace egopd
