// Prompt building (egopressurediff.md §3.2-§3.3): field formatting and clause dropping.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "pipeline/prompt.h"

namespace egopd {
namespace {

PromptFields full() {
  return {{"obj_name", "a CocaCola"}, {"weight", "355g"},     {"material", "aluminum"}, {"gender", "male"},
          {"age", "25"},              {"subj_weight", "74kg"}, {"bodyfat", "25%"}};
}

TEST(Prompt, FullTemplate) {
  EXPECT_EQ(build_prompt(full()).value(),
            "This video shows the action of picking up a CocaCola. The weight of a CocaCola is 355g, and its surface "
            "material is aluminum. The person performing the action is male, 25 years of age, weighing 74kg and "
            "having 25% body fat.");
}

TEST(Prompt, MissingObjectName) {
  PromptFields f = {{"weight", "355g"}, {"material", "aluminum"}};
  EXPECT_EQ(build_prompt(f).value(),
            "This video shows the action of picking up an object. The weight of the object is 355g, and its surface "
            "material is aluminum.");
  f["obj_name"] = "n/a";  // "n/a" and "" count as missing
  EXPECT_EQ(build_prompt(f), build_prompt({{"weight", "355g"}, {"material", "aluminum"}, {"obj_name", ""}}));
}

TEST(Prompt, WeightOnlyAndMaterialOnly) {
  EXPECT_EQ(build_prompt({{"obj_name", "a CocaCola"}, {"weight", "355g"}}).value(),
            "This video shows the action of picking up a CocaCola. The weight of a CocaCola is 355g.");
  EXPECT_EQ(build_prompt({{"obj_name", "a CocaCola"}, {"material", "aluminum"}}).value(),
            "This video shows the action of picking up a CocaCola. The surface material of a CocaCola is aluminum.");
}

TEST(Prompt, SubjectItems) {
  const std::string head = "This video shows the action of picking up an object. The person performing the action is ";
  EXPECT_EQ(build_prompt({{"gender", "male"}}).value(), head + "male.");
  EXPECT_EQ(build_prompt({{"age", "25"}, {"bodyfat", "25%"}}).value(), head + "25 years of age and having 25% body fat.");
  EXPECT_EQ(build_prompt({{"gender", "female"}, {"age", "31"}, {"subj_weight", "60kg"}, {"bodyfat", "22%"}}).value(),
            head + "female, 31 years of age, weighing 60kg and having 22% body fat.");
}

TEST(Prompt, AllMissingIsNoTextMode) {
  EXPECT_FALSE(build_prompt({}).has_value());
  EXPECT_FALSE(build_prompt({{"weight", ""}, {"material", "n/a"}}).has_value());
  EXPECT_FALSE(prompt_fields_from_json(nlohmann::json::object(), "meta").size());
}

TEST(Prompt, FieldFormatting) {
  EXPECT_EQ(format_prompt_field("weight", 355, "m"), "355g");
  EXPECT_EQ(format_prompt_field("weight", 0.5, "m"), "0.5g");
  EXPECT_EQ(format_prompt_field("weight", 355.0, "m"), "355g");
  EXPECT_EQ(format_prompt_field("subj_weight", 74, "m"), "74kg");
  EXPECT_EQ(format_prompt_field("bodyfat", 25, "m"), "25%");
  EXPECT_EQ(format_prompt_field("age", 25, "m"), "25");
  EXPECT_EQ(format_prompt_field("weight", "about 1kg", "m"), "about 1kg");  // strings verbatim
  EXPECT_THROW(format_prompt_field("weight", nlohmann::json::array(), "m"), Error);
}

TEST(Prompt, FieldsFromJson) {
  const nlohmann::json meta = {
      {"obj_name", "a CocaCola"}, {"weight", 355}, {"bodyfat", 25}, {"category", "bottle"}, {"age", nullptr}};
  std::vector<std::string> unknown;
  const PromptFields f = prompt_fields_from_json(meta, "meta", &unknown);
  EXPECT_EQ(f.size(), 3u);  // nulls left out
  EXPECT_EQ(unknown, std::vector<std::string>{"category"});  // reported to the caller, never dropped silently
  EXPECT_THROW(prompt_fields_from_json(meta, "meta"), Error);  // strict readers (manifests): an error
  EXPECT_EQ(f.at("weight"), "355g");
  EXPECT_EQ(f.at("bodyfat"), "25%");
  EXPECT_THROW(prompt_fields_from_json({{"weight", true}}, "meta"), Error);
}

}  // namespace
}  // namespace egopd
