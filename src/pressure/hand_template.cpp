#include "pressure/hand_template.h"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/install_dirs.h"
#include "core/json_text.h"

namespace egopd {
namespace {

constexpr const char* kFormat = "egopd-hand-template/1";
constexpr const char* kDefaultFile = "synthetic_right_hand.json";

const char* const kRegionNames[] = {"tip_thumb", "tip_index", "tip_middle", "tip_ring", "tip_little", "palm",
                                    "seg_thumb", "seg_index", "seg_middle", "seg_ring", "seg_little", "other"};

[[noreturn]] void fail(const std::string& source, const std::string& field, const std::string& why) {
  throw Error(source + ": field '" + field + "': " + why);
}

double finite_number(const nlohmann::json& v, const std::string& source, const std::string& field) {
  if (!v.is_number()) fail(source, field, "expected a number");
  const double d = v.get<double>();
  if (!std::isfinite(d)) fail(source, field, "not a finite number");
  return d;
}

Region parse_region(const nlohmann::json& v, const std::string& source, const std::string& field) {
  if (!v.is_string()) fail(source, field, "expected a region name string");
  const std::string s = v.get<std::string>();
  for (int r = 0; r <= int(Region::Other); ++r)
    if (s == kRegionNames[r]) return Region(r);
  fail(source, field, "unknown region '" + s + "' (expected tip_thumb..tip_little, palm, seg_thumb..seg_little, other)");
}

void validate(const std::vector<Sensor>& sensors, std::vector<Point2>& outline, const std::string& source) {
  if (sensors.empty()) fail(source, "sensors", "no sensors");
  for (size_t i = 0; i < sensors.size(); ++i) {
    const auto& s = sensors[i];
    const std::string f = "sensors[" + std::to_string(i) + "]";
    if (s.id != int(i)) fail(source, f + ".id", "ids must be 0..M-1 in order (got " + std::to_string(s.id) + ")");
    if (!std::isfinite(s.grid.x) || !std::isfinite(s.grid.y)) fail(source, f, "non-finite coordinates");
  }
  // A repeated closing vertex is harmless for the even-odd rule but is dropped to keep one convention.
  if (outline.size() > 1 && outline.front().x == outline.back().x && outline.front().y == outline.back().y)
    outline.pop_back();
  if (outline.size() < 3) fail(source, "outline", "a polygon needs at least 3 distinct vertices");
  for (const auto& p : outline)
    if (!std::isfinite(p.x) || !std::isfinite(p.y)) fail(source, "outline", "non-finite vertex");
}

}  // namespace

const char* region_name(Region r) { return kRegionNames[int(r)]; }

HandTemplate HandTemplate::load(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(path + ": cannot open hand template file");
  std::stringstream ss;
  ss << in.rdbuf();
  nlohmann::json doc;
  try {
    doc = parse_json(ss.str());
  } catch (const nlohmann::json::parse_error& e) {
    throw Error(path + ": not valid JSON (byte " + std::to_string(e.byte) + ")");
  } catch (const nlohmann::json::exception&) {  // e.g. a number too large for a double (found by fuzz_configs)
    throw Error(path + ": not valid JSON (a number out of range)");
  }
  return parse(doc, path);
}

HandTemplate HandTemplate::parse(const nlohmann::json& doc, const std::string& source) {
  if (!doc.is_object()) throw Error(source + ": expected a JSON object");
  if (!doc.contains("format") || !doc["format"].is_string()) fail(source, "format", "missing (expected \"" + std::string(kFormat) + "\")");
  if (doc["format"].get<std::string>() != kFormat)
    fail(source, "format", "unsupported '" + doc["format"].get<std::string>() + "' (expected \"" + kFormat + "\")");

  HandTemplate t;
  t.source_ = source;
  t.name_ = doc.contains("name") && doc["name"].is_string() ? doc["name"].get<std::string>() : std::string("unnamed");
  if (doc.contains("synthetic")) {
    if (!doc["synthetic"].is_boolean()) fail(source, "synthetic", "expected true or false");
    t.synthetic_ = doc["synthetic"].get<bool>();
  }
  bool flip_y = false;
  if (doc.contains("coordinate_system")) {
    const auto& cs = doc["coordinate_system"];
    if (!cs.is_object()) fail(source, "coordinate_system", "expected an object");
    if (cs.contains("y_axis")) {
      const auto& y = cs["y_axis"];
      if (!y.is_string() || (y != "up" && y != "down")) fail(source, "coordinate_system.y_axis", "expected \"up\" or \"down\"");
      flip_y = y == "up";
    }
  }
  const double ys = flip_y ? -1.0 : 1.0;

  if (!doc.contains("sensors") || !doc["sensors"].is_array()) fail(source, "sensors", "missing or not an array");
  const auto& js = doc["sensors"];
  std::vector<Sensor> sensors(js.size());
  std::vector<bool> seen(js.size(), false);
  for (size_t i = 0; i < js.size(); ++i) {
    const std::string f = "sensors[" + std::to_string(i) + "]";
    const auto& e = js[i];
    if (!e.is_object()) fail(source, f, "expected an object");
    for (const char* k : {"id", "x", "y", "region"})
      if (!e.contains(k)) fail(source, f + "." + k, "missing");
    if (!e["id"].is_number_integer()) fail(source, f + ".id", "expected an integer");
    const int64_t id = e["id"].get<int64_t>();
    if (id < 0 || id >= int64_t(js.size()))
      fail(source, f + ".id", std::to_string(id) + " out of range 0.." + std::to_string(js.size() - 1));
    if (seen[id]) fail(source, f + ".id", "duplicate id " + std::to_string(id));
    seen[id] = true;
    Sensor s;
    s.id = int(id);
    s.grid = {finite_number(e["x"], source, f + ".x"), ys * finite_number(e["y"], source, f + ".y")};
    s.region = parse_region(e["region"], source, f + ".region");
    sensors[id] = s;  // the vector index is the id, whatever the file order
  }

  if (!doc.contains("outline") || !doc["outline"].is_array()) fail(source, "outline", "missing or not an array");
  std::vector<Point2> outline;
  for (size_t i = 0; i < doc["outline"].size(); ++i) {
    const auto& v = doc["outline"][i];
    const std::string f = "outline[" + std::to_string(i) + "]";
    if (!v.is_array() || v.size() != 2) fail(source, f, "expected [x, y]");
    outline.push_back({finite_number(v[0], source, f), ys * finite_number(v[1], source, f)});
  }
  validate(sensors, outline, source);
  t.sensors_ = std::move(sensors);
  t.outline_ = std::move(outline);
  t.index_regions();
  return t;
}

HandTemplate HandTemplate::from_parts(std::string name, std::vector<Sensor> sensors, std::vector<Point2> outline,
                                      bool synthetic) {
  HandTemplate t;
  t.source_ = "template '" + name + "'";
  validate(sensors, outline, t.source_);
  t.name_ = std::move(name);
  t.synthetic_ = synthetic;
  t.sensors_ = std::move(sensors);
  t.outline_ = std::move(outline);
  t.index_regions();
  return t;
}

void HandTemplate::index_regions() {
  for (auto& g : groups_) g.clear();
  for (auto& p : parts_) p.clear();
  for (const auto& s : sensors_) {
    const int r = int(s.region);
    if (r < kNumCopParts)
      parts_[r].push_back(s.id);
    else if (s.region != Region::Other)
      groups_[r - kNumCopParts].push_back(s.id);
  }
  // Stabilisation averages exactly six taxels per finger (pressure.md §2); a template either defines all five
  // groups that way or none (then stabilisation leaves readings unchanged).
  bool any = false;
  for (const auto& g : groups_) any = any || !g.empty();
  if (!any) return;
  for (int k = 0; k < kNumSegmentGroups; ++k)
    if (int(groups_[k].size()) != kSegmentGroupSize)
      fail(source_, "sensors", std::string("region '") + kRegionNames[kNumCopParts + k] + "' has " +
                                   std::to_string(groups_[k].size()) + " sensors (expected exactly 6)");
}

std::string default_template_path() {
  namespace fs = std::filesystem;
  std::vector<fs::path> candidates;
  if (const char* env = std::getenv("EGOPD_TEMPLATE"); env && *env) {
    if (!fs::is_regular_file(env)) throw Error(std::string("EGOPD_TEMPLATE: no such file: ") + env);
    return env;
  }
  std::error_code ec;
  for (const fs::path& dir : installed_data_candidates("templates")) candidates.push_back(dir / kDefaultFile);
#ifdef EGOPD_TEMPLATE_DIR
  candidates.push_back(fs::path(EGOPD_TEMPLATE_DIR) / kDefaultFile);
#endif
  for (const auto& c : candidates)
    if (fs::is_regular_file(c, ec)) return c.string();
  std::string looked;
  for (const auto& c : candidates) looked += (looked.empty() ? "" : ", ") + c.string();
  throw Error("default hand template " + std::string(kDefaultFile) + " not found (looked in: " + looked +
              "); pass --template FILE or set EGOPD_TEMPLATE");
}

}  // namespace egopd
