// Template loading: the shipped synthetic default and one-line errors naming file and field.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/error.h"
#include "core/json_text.h"
#include "pressure/hand_template.h"
#include "pressure/renderer.h"

namespace egopd {
namespace {

const std::string kShipped = std::string(EGOPD_TEST_DATA) + "/../data/templates/synthetic_right_hand.json";

nlohmann::json minimal() {
  return parse_json(R"({
    "format": "egopd-hand-template/1", "name": "tiny", "synthetic": true,
    "sensors": [{"id": 1, "x": 2.0, "y": 3.0, "region": "palm"},
                {"id": 0, "x": 1.0, "y": 1.0, "region": "tip_thumb"}],
    "outline": [[0, 0], [4, 0], [4, 4], [0, 4]]})");
}

std::string error_of(const nlohmann::json& j) {
  try {
    HandTemplate::parse(j, "t.json");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(HandTemplate, ShippedDefaultIsPlausibleAndSynthetic) {
  const HandTemplate t = HandTemplate::load(kShipped);
  EXPECT_TRUE(t.synthetic());
  EXPECT_EQ(t.num_sensors(), 162);
  for (const auto& g : t.segment_groups()) EXPECT_EQ(g.size(), 6u);
  for (const auto& p : t.cop_parts()) EXPECT_FALSE(p.empty());
  for (const auto& s : t.sensors()) EXPECT_TRUE(inside_polygon(t.outline(), s.grid.x, s.grid.y)) << s.id;
  const PressureRenderer r(t, 256);
  EXPECT_TRUE(r.warnings().empty());
}

TEST(HandTemplate, ParsesAndIndexesById) {
  const HandTemplate t = HandTemplate::parse(minimal(), "t.json");
  EXPECT_EQ(t.name(), "tiny");
  ASSERT_EQ(t.num_sensors(), 2);
  EXPECT_EQ(t.sensors()[0].region, Region::TipThumb);
  EXPECT_EQ(t.sensors()[1].grid.x, 2.0);
  EXPECT_EQ(t.cop_parts()[int(Region::Palm)], std::vector<int>{1});
  for (const auto& g : t.segment_groups()) EXPECT_TRUE(g.empty());  // no groups: stabilisation is a no-op
}

TEST(HandTemplate, YAxisUpIsFlipped) {
  auto j = minimal();
  j["coordinate_system"] = {{"units", "grid"}, {"y_axis", "up"}};
  const HandTemplate t = HandTemplate::parse(j, "t.json");
  EXPECT_EQ(t.sensors()[1].grid.y, -3.0);
  EXPECT_EQ(t.outline()[2].y, -4.0);
}

TEST(HandTemplate, RepeatedClosingVertexDropped) {
  auto j = minimal();
  j["outline"].push_back({0, 0});
  EXPECT_EQ(HandTemplate::parse(j, "t.json").outline().size(), 4u);
}

// Found by fuzz_configs: a number too large for a double escaped as a raw JSON library exception.
TEST(HandTemplate, UnparsableFilesAreOneLineErrors) {
  const std::filesystem::path p = std::filesystem::temp_directory_path() / ("egopd-tmpl-" + std::to_string(::getpid()));
  for (const char* text : {"{\"a\": 8888888888888888888888888888888888888E8888888}", "{\"a\": ", "\xff"}) {
    std::ofstream(p) << text;
    try {
      HandTemplate::load(p.string());
      ADD_FAILURE() << "accepted: " << text;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(": not valid JSON"), std::string::npos) << e.what();
    }
  }
  std::filesystem::remove(p);
}

TEST(HandTemplate, ErrorsNameFileAndField) {
  auto j = minimal();
  j.erase("format");
  EXPECT_NE(error_of(j).find("t.json: field 'format'"), std::string::npos) << error_of(j);
  j = minimal();
  j["format"] = "other/2";
  EXPECT_NE(error_of(j).find("field 'format'"), std::string::npos);
  j = minimal();
  j["sensors"][0]["id"] = 0;
  EXPECT_NE(error_of(j).find("field 'sensors[1].id': duplicate id 0"), std::string::npos) << error_of(j);
  j = minimal();
  j["sensors"][0]["id"] = 5;
  EXPECT_NE(error_of(j).find("field 'sensors[0].id'"), std::string::npos);
  j = minimal();
  j["sensors"][1]["region"] = "thumbnail";
  EXPECT_NE(error_of(j).find("field 'sensors[1].region': unknown region 'thumbnail'"), std::string::npos);
  j = minimal();
  j["sensors"][0]["x"] = "two";
  EXPECT_NE(error_of(j).find("field 'sensors[0].x': expected a number"), std::string::npos);
  j = minimal();
  j["sensors"][0].erase("y");
  EXPECT_NE(error_of(j).find("field 'sensors[0].y': missing"), std::string::npos);
  j = minimal();
  j["outline"] = {{0, 0}, {1, 1}};
  EXPECT_NE(error_of(j).find("field 'outline'"), std::string::npos);
  j = minimal();
  j["outline"][1] = {1, 2, 3};
  EXPECT_NE(error_of(j).find("field 'outline[1]'"), std::string::npos);
  j = minimal();
  j["synthetic"] = "yes";
  EXPECT_NE(error_of(j).find("field 'synthetic'"), std::string::npos);
}

TEST(HandTemplate, SegmentGroupsNeedSixTaxels) {
  auto j = minimal();
  j["sensors"][0]["region"] = "seg_index";  // one group with 1 taxel, the others empty
  EXPECT_NE(error_of(j).find("region 'seg_thumb' has 0 sensors (expected exactly 6)"), std::string::npos)
      << error_of(j);
}

TEST(HandTemplate, MissingOrBrokenFile) {
  try {
    HandTemplate::load("/nonexistent/hand.json");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "/nonexistent/hand.json: cannot open hand template file");
  }
  EXPECT_THROW(HandTemplate::load(std::string(EGOPD_TEST_DATA) + "/CMakeLists.txt"), Error);  // not JSON
}

TEST(HandTemplate, DefaultPathHonoursEnvironment) {
  ::setenv("EGOPD_TEMPLATE", "/nonexistent/hand.json", 1);
  EXPECT_THROW(default_template_path(), Error);
  ::setenv("EGOPD_TEMPLATE", kShipped.c_str(), 1);
  EXPECT_EQ(default_template_path(), kShipped);
  ::unsetenv("EGOPD_TEMPLATE");
  EXPECT_EQ(HandTemplate::load(default_template_path()).num_sensors(), 162);  // source-tree fallback
}

}  // namespace
}  // namespace egopd
