#include "convert/inspect.h"

#include <cstdio>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>

#include "convert/model_check.h"
#include "convert/tensor_io.h"
#include "core/error.h"
#include "core/finite_check.h"
#include "pipeline/synthetic_model.h"

namespace egopd {
namespace fs = std::filesystem;

namespace {

std::string human_bytes(uint64_t b) {
  char buf[32];
  if (b >= (uint64_t(1) << 30)) std::snprintf(buf, sizeof buf, "%.2f GiB", double(b) / double(uint64_t(1) << 30));
  else if (b >= (uint64_t(1) << 20)) std::snprintf(buf, sizeof buf, "%.2f MiB", double(b) / double(uint64_t(1) << 20));
  else std::snprintf(buf, sizeof buf, "%llu B", static_cast<unsigned long long>(b));
  return buf;
}

struct Totals {
  uint64_t tensors = 0, elements = 0, bytes = 0;
  std::map<std::string, uint64_t> per_dtype;  // dtype -> tensors
  std::vector<std::string> non_finite;        // "name: k of n values are NaN or Inf"
};

// Every value of every float tensor is read: a single NaN or Inf in a download makes the whole model unusable.
Totals list_map(const WeightMap& w, std::ostream& out, bool list) {
  Totals t;
  for (const auto& k : w.keys()) {
    const StoredTensor* s = w.find(k);
    if (list) out << "  " << k << "  " << dtype_name(s->dtype) << "  " << s->shape_str() << "  " << s->nbytes << "\n";
    if (is_float_weight(s->dtype)) {
      const Tensor f = s->to_f32();
      const int64_t bad = count_non_finite(f.data(), f.numel());
      if (bad > 0)
        t.non_finite.push_back(k + ": " + std::to_string(bad) + " of " + std::to_string(f.numel()) +
                               " values are NaN or Inf");
    }
    ++t.tensors;
    t.elements += uint64_t(s->numel());
    t.bytes += s->nbytes;
    ++t.per_dtype[dtype_name(s->dtype)];
  }
  return t;
}

void print_totals(const Totals& t, std::ostream& out, const std::string& indent) {
  out << indent << t.tensors << " tensors, " << t.elements << " values, " << human_bytes(t.bytes) << " (";
  bool first = true;
  for (const auto& [d, n] : t.per_dtype) {
    out << (first ? "" : ", ") << d << " x" << n;
    first = false;
  }
  out << ")\n";
}

// Which component a standalone folder is, from its config's class.
std::string folder_of_config(const Config& c) {
  const std::string cls = c.get_string("_class_name", "");
  if (cls == "ControlNetConditioningEmbedding") return "mask_encoder";
  std::string arch;
  if (c.json().contains("architectures") && c.json()["architectures"].is_array() && !c.json()["architectures"].empty())
    arch = c.json()["architectures"][0].get<std::string>();
  for (const auto& m : model_components())
    if (cls == m.class_name || arch == m.class_name) return m.folder;
  if (arch == "CLIPTextModelWithProjection") return "text_encoder";
  return "";
}

// One component folder: config, tensors, key check. Returns the number of problems.
size_t inspect_component(const fs::path& dir, const std::string& folder, std::ostream& out, bool list, Totals* all) {
  const ModelComponent& mc = model_component(folder);
  out << folder << "/\n";
  const auto files = resolve_weight_files(dir.string(), mc.stem);
  if (files.empty()) {
    out << "  problem: no " << mc.stem << ".safetensors (or sharded index, or variant)\n";
    return 1;
  }
  out << "  weights: ";
  for (size_t i = 0; i < files.size(); ++i) out << (i ? ", " : "") << fs::path(files[i]).filename().string();
  out << "\n";
  size_t problems = 0;
  try {
    const Config cfg = Config::load((dir / "config.json").string());
    const WeightMap w = open_weights_dir(dir.string(), mc.stem, folder);
    const Totals t = list_map(w, out, list);
    print_totals(t, out, "  ");
    for (const std::string& n : t.non_finite) out << "  problem: non-finite " << n << "\n";
    problems += t.non_finite.size();
    all->tensors += t.tensors;
    all->elements += t.elements;
    all->bytes += t.bytes;
    for (const auto& [d, n] : t.per_dtype) all->per_dtype[d] += n;
    bool pifr = false;
    if (folder == "unet" && cfg.has("pifr")) {
      pifr = cfg.sub("pifr").get_bool("enabled", true);
      out << "  config: pifr " << (pifr ? "enabled" : "disabled") << ", text_dim "
          << cfg.sub("pifr").get_int("text_dim", 0) << "\n";
    }
    std::map<std::string, StoredInfo> stored;
    for (const auto& k : w.keys()) stored[k] = {w.find(k)->dtype, w.find(k)->shape};
    const auto expected = component_parameters(folder, cfg);
    const KeyCheck c = check_keys(folder, expected, stored, pifr);
    out << "  check: ";
    if (c.ok()) {
      out << "ok (" << expected.size() << " expected tensors present with their shapes)\n";
    } else {
      out << c.problems() << " problems\n";
      for (const auto& m : c.missing) out << "    missing " << m << "\n";
      for (const auto& m : c.wrong_shape) out << "    shape " << m << "\n";
      for (const auto& m : c.unexpected) out << "    unexpected " << m << "\n";
      for (const auto& m : c.wrong_dtype) out << "    dtype " << m << " (weights must be F32, F16, BF16 or I8 + _scale)\n";
    }
    problems += c.problems();
  } catch (const Error& e) {
    out << "  problem: " << e.what() << "\n";
    ++problems;
  }
  return problems;
}

size_t inspect_model_dir(const fs::path& root, std::ostream& out, bool list) {
  size_t problems = 0;
  Totals all;
  out << "model directory " << root.string() << "\n";
  if (!fs::is_regular_file(root / "model_index.json")) {
    out << "problem: no model_index.json\n";
    ++problems;
  }
  for (const auto& mc : model_components()) {
    const fs::path d = root / mc.folder;
    if (!fs::is_directory(d)) {
      const bool optional = std::string(mc.folder) == "text_encoder" || std::string(mc.folder) == "mask_encoder";
      out << mc.folder << "/: absent" << (optional ? " (optional)" : "") << "\n";
      problems += optional ? 0 : 1;
      continue;
    }
    problems += inspect_component(d, mc.folder, out, list, &all);
  }
  for (const auto& [folder, file] : {std::pair<const char*, const char*>{"tokenizer", "vocab.json"},
                                     {"tokenizer", "merges.txt"},
                                     {"scheduler", "scheduler_config.json"},
                                     {"feature_extractor", "preprocessor_config.json"}}) {
    const fs::path p = root / folder / file;
    const bool optional = std::string(folder) == "tokenizer" && !fs::is_directory(root / "text_encoder");
    if (fs::is_regular_file(p)) {
      out << folder << "/" << file << ": present\n";
    } else {
      out << folder << "/" << file << ": absent" << (optional ? " (optional)" : "") << "\n";
      problems += optional ? 0 : 1;
    }
  }
  out << "total: ";
  print_totals(all, out, "");
  return problems;
}

}  // namespace

size_t inspect_path(const std::string& path, std::ostream& out, const InspectOptions& options) {
  const fs::path p(path);
  if (fs::is_directory(p)) {
    bool model_dir = fs::exists(p / "model_index.json");
    for (const auto& mc : model_components()) model_dir = model_dir || fs::is_directory(p / mc.folder);
    if (model_dir) {
      const size_t n = inspect_model_dir(p, out, options.list_tensors);
      out << (n ? std::to_string(n) + " problems\n" : std::string("no problems\n"));
      return n;
    }
    const std::string folder = folder_of_config(Config::load((p / "config.json").string()));
    if (folder.empty()) throw Error((p / "config.json").string() + ": cannot tell which model component this is");
    Totals all;
    const size_t n = inspect_component(p, folder, out, options.list_tensors, &all);
    out << (n ? std::to_string(n) + " problems\n" : std::string("no problems\n"));
    return n;
  }
  const WeightMap w = open_weights_path(path, path);
  out << path << "\n";
  const Totals t = list_map(w, out, options.list_tensors);
  print_totals(t, out, "");
  for (const std::string& n : t.non_finite) out << "problem: non-finite " << n << "\n";
  out << (t.non_finite.empty() ? std::string("no problems\n") : std::to_string(t.non_finite.size()) + " problems\n");
  return t.non_finite.size();
}

}  // namespace egopd
