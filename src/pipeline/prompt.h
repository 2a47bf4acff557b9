#pragma once
// Text prompt from object/subject metadata (egopressurediff.md §3): the paper's template with verbatim
// substitution, field formatting (§3.2) and clause dropping for missing attributes (§3.3).
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

namespace egopd {

// Formatted attribute values by field name: obj_name, weight, material, gender, age, subj_weight, bodyfat.
using PromptFields = std::map<std::string, std::string>;

// Reads META.json ({"obj_name": "a CocaCola", "weight": 355, ...}) and formats every known field
// (weight 355 -> "355g", subj_weight 74 -> "74kg", bodyfat 25 -> "25%", strings verbatim). A value of the wrong type
// is an error naming the file and field; an unknown key is one too, unless `unknown_keys` collects them.
PromptFields prompt_fields_from_json(const nlohmann::json& meta, const std::string& source,
                                     std::vector<std::string>* unknown_keys = nullptr);
// --meta: a dataset's metadata file may carry more than the prompt fields (category, hand length, ...): each other
// key gets a warning naming it on stderr and is ignored.
PromptFields load_prompt_fields(const std::string& meta_path);
// Formats one field's raw value ("355" -> "355g" for weight); used by --vary weight=355g,...
std::string format_prompt_field(const std::string& field, const nlohmann::json& value, const std::string& source);

// The prompt, or nullopt when every field is missing (no-text mode). A field is missing if absent, empty or
// "n/a". With a custom template (egopd_defaults.prompt_template) the fields are substituted verbatim and no clause
// is dropped.
std::optional<std::string> build_prompt(const PromptFields& fields);
std::string fill_template(const std::string& tmpl, const PromptFields& fields);

}  // namespace egopd
