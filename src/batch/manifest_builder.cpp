// `egopd manifest`: a manifest from a dataset tree as the EgoPressureDiff release stores it:
//   ROOT/motion_list.txt                one sequence folder per line (relative to ROOT; '#' comments)
//   ROOT/p001-Apple-repeat0000/00005_rgb.png, 00005_mask.png, 00005_pressure.png, ...
// A sequence folder is named <subject>-<object>-<take>: the subject is the text before the first '-', the take the
// text after the last one, the object what lies between. Its frames are the *_rgb images (or all images, or the one
// video file), masks the *_mask images and ground truth the *_pressure heatmaps (or a taxels.csv) when present.
//
// The attribute file (JSON; every section optional) gives the prompt fields per object and per subject and the
// held-out splits:
//   {"objects":  {"Apple": {"obj_name": "an apple", "weight": 180, "material": "organic"}},
//    "subjects": {"p001":  {"gender": "female", "age": 27, "subj_weight": 60, "bodyfat": 22}},
//    "splits":   {"object_held_out": {"objects": ["Apple"]}, "subject_held_out": {"subjects": ["p001"]}}}
// With an attribute file every sequence's object and subject must be listed in it (an error names the one that
// is not); a sequence belongs to each split that holds out its object or its subject.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include "batch/manifest.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/json_text.h"
#include "pipeline/media.h"
#include "pipeline/prompt.h"

namespace egopd {
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

struct SplitRule {
  std::string name;
  std::set<std::string> objects, subjects;
};

struct Attributes {
  std::map<std::string, json> objects, subjects;  // name -> prompt fields (raw JSON values)
  std::vector<SplitRule> splits;
  std::string source;
};

std::map<std::string, json> attribute_section(const json& j, const char* section, const std::set<std::string>& fields,
                                              const std::string& source) {
  std::map<std::string, json> out;
  if (!j.contains(section)) return out;
  if (!j[section].is_object()) throw Error(source + ": '" + section + "' must be an object of name -> fields");
  for (const auto& entry : j[section].items()) {
    const std::string where = source + ": " + section + "." + entry.key();
    if (!entry.value().is_object()) throw Error(where + " must be an object of prompt fields");
    for (const auto& f : entry.value().items())
      if (!fields.count(f.key())) throw Error(where + ": unknown field '" + f.key() + "'");
    prompt_fields_from_json(entry.value(), where);  // checks the value types now, not per sequence
    out[entry.key()] = entry.value();
  }
  return out;
}

std::set<std::string> name_list(const json& j, const char* key, const std::string& where) {
  std::set<std::string> out;
  if (!j.contains(key)) return out;
  if (!j[key].is_array()) throw Error(where + ": '" + key + "' must be a list of names");
  for (const json& e : j[key]) {
    if (!e.is_string()) throw Error(where + ": '" + key + "' must be a list of names");
    out.insert(e.get<std::string>());
  }
  return out;
}

Attributes load_attributes(const std::string& path) {
  Attributes a;
  a.source = path;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path + ": cannot open attribute file");
  json j;
  try {
    j = parse_json(in);
  } catch (const json::exception&) {
    throw Error(path + ": attribute file is not valid JSON");
  }
  if (!j.is_object()) throw Error(path + ": attribute file must be a JSON object");
  for (const auto& item : j.items())
    if (item.key() != "objects" && item.key() != "subjects" && item.key() != "splits" && item.key() != "format")
      throw Error(path + ": unknown section '" + item.key() + "' (objects, subjects, splits)");
  a.objects = attribute_section(j, "objects", {"obj_name", "weight", "material"}, path);
  a.subjects = attribute_section(j, "subjects", {"gender", "age", "subj_weight", "bodyfat"}, path);
  if (j.contains("splits")) {
    if (!j["splits"].is_object()) throw Error(path + ": 'splits' must be an object of split name -> rule");
    for (const auto& s : j["splits"].items()) {
      const std::string where = path + ": splits." + s.key();
      if (!s.value().is_object()) throw Error(where + " must be {\"objects\": [...]} and/or {\"subjects\": [...]}");
      for (const auto& f : s.value().items())
        if (f.key() != "objects" && f.key() != "subjects") throw Error(where + ": unknown field '" + f.key() + "'");
      a.splits.push_back({s.key(), name_list(s.value(), "objects", where), name_list(s.value(), "subjects", where)});
    }
  }
  return a;
}

size_t count_with_suffix(const std::vector<std::string>& files, const std::string& suffix) {
  return files_with_stem_suffix(files, suffix).size();
}

std::string single_video(const fs::path& dir) {
  static const std::set<std::string> kVideo = {".mp4", ".avi", ".mov", ".mkv", ".webm"};
  std::vector<std::string> found;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_regular_file() && kVideo.count(e.path().extension().string())) found.push_back(e.path().string());
  return found.size() == 1 ? found[0] : "";
}

// Sequence folders (relative to root): the list file's lines, or every sub-folder holding images or a video.
std::vector<std::string> sequence_folders(const ManifestBuildOptions& o) {
  std::string list = o.list;
  if (list.empty() && fs::is_regular_file(fs::path(o.root) / "motion_list.txt"))
    list = (fs::path(o.root) / "motion_list.txt").string();
  std::vector<std::string> seqs;
  if (!list.empty()) {
    std::ifstream in(list);
    if (!in) throw Error(list + ": cannot open sequence list");
    std::string line;
    while (std::getline(in, line)) {
      if (!line.empty() && line.back() == '\r') line.pop_back();
      const size_t b = line.find_first_not_of(" \t"), e = line.find_last_not_of(" \t");
      if (b == std::string::npos || line[b] == '#') continue;
      seqs.push_back(line.substr(b, e - b + 1));
    }
    if (seqs.empty()) throw Error(list + ": lists no sequence folders");
    return seqs;
  }
  for (const auto& e : fs::directory_iterator(o.root))
    if (e.is_directory() && e.path().filename().string()[0] != '.') seqs.push_back(e.path().filename().string());
  std::sort(seqs.begin(), seqs.end(), natural_less);
  if (seqs.empty()) throw Error(o.root + ": no sequence folders (and no motion_list.txt)");
  return seqs;
}

// subject, object from <subject>-<object>-<take>; empty when the name has another form.
std::pair<std::string, std::string> subject_and_object(const std::string& name) {
  const size_t first = name.find('-'), last = name.rfind('-');
  if (first == std::string::npos || last == first) return {"", ""};
  return {name.substr(0, first), name.substr(first + 1, last - first - 1)};
}

std::string relative_to(const fs::path& target, const fs::path& base) {
  const fs::path rel = fs::absolute(target).lexically_normal().lexically_relative(base);
  return rel.empty() ? fs::absolute(target).string() : rel.string();
}

ManifestClip clip_of(const std::string& seq, const ManifestBuildOptions& o, const Attributes* attrs,
                     const fs::path& base) {
  const fs::path dir = fs::path(o.root) / seq;
  const std::string where = dir.string();
  if (!fs::is_directory(dir)) throw Error(where + ": sequence folder does not exist");
  ManifestClip c;
  c.id = fs::path(seq).lexically_normal().filename().string();
  if (c.id.empty()) c.id = fs::path(seq).lexically_normal().parent_path().filename().string();
  const std::vector<std::string> images = list_image_files(dir.string());
  if (!images.empty()) {
    c.frames = relative_to(dir, base);
  } else {
    const std::string video = single_video(dir);
    if (video.empty()) throw Error(where + ": no frames (no images and not exactly one video file)");
    c.frames = relative_to(video, base);
  }
  const size_t rgb = count_with_suffix(images, "_rgb");
  if (rgb == 0 && (count_with_suffix(images, "_mask") > 0 || count_with_suffix(images, "_pressure") > 0))
    throw Error(where + ": *_mask or *_pressure images but no *_rgb frames beside them");
  if (count_with_suffix(images, "_mask") > 0) {
    if (count_with_suffix(images, "_mask") != rgb)
      throw Error(where + ": " + std::to_string(count_with_suffix(images, "_mask")) + " *_mask images but " +
                  std::to_string(rgb) + " *_rgb frames");
    c.masks = c.frames;
  }
  if (count_with_suffix(images, "_pressure") > 0) {
    if (count_with_suffix(images, "_pressure") != rgb)
      throw Error(where + ": " + std::to_string(count_with_suffix(images, "_pressure")) +
                  " *_pressure images but " + std::to_string(rgb) + " *_rgb frames");
    c.gt = c.frames;
  } else if (fs::is_regular_file(dir / "taxels.csv")) {
    c.gt = relative_to(dir / "taxels.csv", base);
  }
  if (attrs) {
    const auto [subject, object] = subject_and_object(c.id);
    if (subject.empty()) throw Error(where + ": name is not <subject>-<object>-<take>, so attributes cannot apply");
    const auto obj = attrs->objects.find(object);
    if (obj == attrs->objects.end())
      throw Error(attrs->source + ": no attributes for object '" + object + "' (sequence " + c.id + ")");
    const auto subj = attrs->subjects.find(subject);
    if (subj == attrs->subjects.end())
      throw Error(attrs->source + ": no attributes for subject '" + subject + "' (sequence " + c.id + ")");
    json fields = obj->second;
    fields.update(subj->second);
    c.meta = prompt_fields_from_json(fields, attrs->source);
    for (const SplitRule& r : attrs->splits)
      if (r.objects.count(object) || r.subjects.count(subject)) c.splits.push_back(r.name);
  }
  return c;
}

}  // namespace

size_t build_manifest(const ManifestBuildOptions& o) {
  if (!fs::is_directory(o.root)) throw Error(o.root + ": dataset root folder does not exist");
  std::optional<Attributes> attrs;
  if (!o.attributes.empty()) attrs = load_attributes(o.attributes);
  const fs::path base = fs::absolute(fs::path(o.out)).lexically_normal().parent_path();
  std::string text;
  std::set<std::string> ids;
  size_t n = 0;
  for (const std::string& seq : sequence_folders(o)) {
    const ManifestClip c = clip_of(seq, o, attrs ? &*attrs : nullptr, base);
    if (!ids.insert(c.id).second) throw Error(o.root + ": two sequences named '" + c.id + "'");
    try {
      text += manifest_line(c) + "\n";
    } catch (const nlohmann::json::exception&) {
      throw Error((fs::path(o.root) / seq).string() + ": path or attribute is not valid UTF-8");
    }
    ++n;
  }
  write_file_atomic(o.out, text);
  return n;
}

}  // namespace egopd
