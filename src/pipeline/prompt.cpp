#include "pipeline/prompt.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <vector>

#include "core/error.h"
#include "core/json_text.h"

namespace egopd {

static const char* const kFields[] = {"obj_name", "weight", "material", "gender", "age", "subj_weight", "bodyfat"};

static std::string shortest_decimal(double v) {
  char buf[64];
  for (int prec = 1; prec <= 17; ++prec) {
    std::snprintf(buf, sizeof buf, "%.*g", prec, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

std::string format_prompt_field(const std::string& field, const nlohmann::json& v, const std::string& source) {
  if (v.is_string()) return v.get<std::string>();
  if (!v.is_number()) throw Error(source + ": field '" + field + "' must be a string or a number");
  const double x = v.get<double>();
  const std::string num = (std::floor(x) == x && std::fabs(x) < 1e15) ? std::to_string(int64_t(x)) : shortest_decimal(x);
  if (field == "weight") return num + "g";
  if (field == "subj_weight") return num + "kg";
  if (field == "bodyfat") return num + "%";
  return num;
}

PromptFields prompt_fields_from_json(const nlohmann::json& meta, const std::string& source,
                                     std::vector<std::string>* unknown_keys) {
  if (!meta.is_object()) throw Error(source + ": metadata must be a JSON object");
  for (const auto& item : meta.items()) {  // a misspelt field must not silently vanish from the prompt
    bool known = false;
    for (const char* k : kFields) known = known || item.key() == k;
    if (known) continue;
    if (!unknown_keys)
      throw Error(source + ": unknown field '" + item.key() +
                  "' (fields: obj_name, weight, material, gender, age, subj_weight, bodyfat)");
    unknown_keys->push_back(item.key());
  }
  PromptFields f;
  for (const char* k : kFields)
    if (meta.contains(k) && !meta[k].is_null()) f[k] = format_prompt_field(k, meta[k], source);
  return f;
}

PromptFields load_prompt_fields(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(path + ": cannot open metadata file");
  nlohmann::json j;
  try {
    j = parse_json(in);
  } catch (const std::exception&) {
    throw Error(path + ": metadata is not valid JSON");
  }
  std::vector<std::string> unknown;
  PromptFields f = prompt_fields_from_json(j, path, &unknown);
  for (const std::string& k : unknown)
    std::fprintf(stderr, "warning: %s: field '%s' is not a prompt field and is ignored (fields: obj_name, weight, "
                 "material, gender, age, subj_weight, bodyfat)\n", path.c_str(), k.c_str());
  return f;
}

static bool present(const PromptFields& f, const char* k) {
  auto it = f.find(k);
  return it != f.end() && !it->second.empty() && it->second != "n/a";
}

std::optional<std::string> build_prompt(const PromptFields& f) {
  bool any = false;
  for (const char* k : kFields) any = any || present(f, k);
  if (!any) return std::nullopt;
  const auto get = [&](const char* k) { return f.at(k); };
  std::vector<std::string> sentences;
  const std::string obj = present(f, "obj_name") ? get("obj_name") : "the object";
  sentences.push_back(present(f, "obj_name") ? "This video shows the action of picking up " + obj + "."
                                             : "This video shows the action of picking up an object.");
  const bool w = present(f, "weight"), m = present(f, "material");
  if (w && m) {
    sentences.push_back("The weight of " + obj + " is " + get("weight") + ", and its surface material is " +
                        get("material") + ".");
  } else if (w) {
    sentences.push_back("The weight of " + obj + " is " + get("weight") + ".");
  } else if (m) {
    sentences.push_back("The surface material of " + obj + " is " + get("material") + ".");
  }
  std::vector<std::string> items;
  if (present(f, "gender")) items.push_back(get("gender"));
  if (present(f, "age")) items.push_back(get("age") + " years of age");
  if (present(f, "subj_weight")) items.push_back("weighing " + get("subj_weight"));
  if (present(f, "bodyfat")) items.push_back("having " + get("bodyfat") + " body fat");
  if (!items.empty()) {
    std::string s = items[0];
    if (items.size() >= 2) {
      s.clear();
      for (size_t i = 0; i + 1 < items.size(); ++i) s += (i ? ", " : "") + items[i];
      s += " and " + items.back();
    }
    sentences.push_back("The person performing the action is " + s + ".");
  }
  std::string out;
  for (const auto& s : sentences) out += (out.empty() ? "" : " ") + s;
  return out;
}

std::string fill_template(const std::string& tmpl, const PromptFields& f) {
  std::string out;
  for (size_t i = 0; i < tmpl.size();) {
    if (tmpl[i] == '{') {
      const size_t close = tmpl.find('}', i);
      if (close != std::string::npos) {
        const std::string key = tmpl.substr(i + 1, close - i - 1);
        auto it = f.find(key);
        out += it != f.end() ? it->second : "";
        i = close + 1;
        continue;
      }
    }
    out += tmpl[i++];
  }
  return out;
}

}  // namespace egopd
