#pragma once
// Canonical hand template (pressure.md §4.1): the glove's taxel positions in grid units, their region labels and
// the hand outline. The taxel vector index is the sensor id. Loaded from a JSON file; every load error is one line
// naming the file and the field.
#include <array>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

namespace egopd {

struct Point2 {
  double x = 0;
  double y = 0;
};

// The 6 CoP parts come first (in the order the metrics report them), then the 5 stabilisation groups.
enum class Region {
  TipThumb, TipIndex, TipMiddle, TipRing, TipLittle, Palm,
  SegThumb, SegIndex, SegMiddle, SegRing, SegLittle,
  Other,
};
constexpr int kNumCopParts = 6;          // tip_thumb .. tip_little, palm
constexpr int kNumSegmentGroups = 5;     // seg_thumb .. seg_little
constexpr int kSegmentGroupSize = 6;     // taxels per stabilisation group
const char* region_name(Region r);       // "tip_thumb", ...

struct Sensor {
  int id = 0;
  Point2 grid;  // template coordinates, y down (files with y_axis "up" are flipped at load)
  Region region = Region::Other;
};

class HandTemplate {
 public:
  // Reads and validates a template file (format "egopd-hand-template/1").
  static HandTemplate load(const std::string& path);
  // Same validation on an already-parsed document; `source` names it in errors.
  static HandTemplate parse(const nlohmann::json& doc, const std::string& source);
  // Built in code (tests, tools); sensors[i].id must equal i. Validated like a file.
  static HandTemplate from_parts(std::string name, std::vector<Sensor> sensors, std::vector<Point2> outline,
                                 bool synthetic);

  const std::string& name() const { return name_; }
  const std::string& source() const { return source_; }
  // True for layouts that are not a real glove; tools must say so wherever they use one.
  bool synthetic() const { return synthetic_; }
  int num_sensors() const { return int(sensors_.size()); }
  const std::vector<Sensor>& sensors() const { return sensors_; }
  const std::vector<Point2>& outline() const { return outline_; }  // closed polygon, last vertex not repeated
  // Sensor ids of each stabilisation group G_k (thumb..little); all empty if the template defines none.
  const std::array<std::vector<int>, kNumSegmentGroups>& segment_groups() const { return groups_; }
  // Sensor ids of each CoP part R_r (tip_thumb..tip_little, palm); a part may be empty.
  const std::array<std::vector<int>, kNumCopParts>& cop_parts() const { return parts_; }

 private:
  void index_regions();  // fills groups_/parts_ and checks the group sizes
  std::string name_, source_;
  bool synthetic_ = false;
  std::vector<Sensor> sensors_;
  std::vector<Point2> outline_;
  std::array<std::vector<int>, kNumSegmentGroups> groups_;
  std::array<std::vector<int>, kNumCopParts> parts_;
};

// The template shipped with egopd (synthetic). Looked up in order: $EGOPD_TEMPLATE (a file), the install
// location <bin>/../share/egopd/templates/, the source tree's data/templates/. Error if none exists.
std::string default_template_path();

}  // namespace egopd
