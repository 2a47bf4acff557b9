#include "convert/from_original.h"

#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>

#include "convert/model_check.h"
#include "convert/original_mapping.h"
#include "core/error.h"
#include "pipeline/synthetic_model.h"

namespace egopd {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

struct Planned {
  const StoredTensor* source = nullptr;  // null: synthesised (identity quant_conv)
  KeyTransform transform = KeyTransform::Copy;
  DType dtype = DType::F32;
  std::vector<int64_t> shape;
  std::function<void(uint8_t*)> synth;
};

using Plan = std::map<std::string, std::map<std::string, Planned>>;  // component -> key -> tensor

bool starts(const std::string& s, const std::string& p) { return s.compare(0, p.size(), p) == 0; }

// quant_conv as the identity [2L, 2L, 1, 1] with zero bias, for checkpoints whose encoder has none.
void add_identity_quant_conv(Plan& plan, int64_t latent_channels) {
  auto& vae = plan["vae"];
  auto ref = vae.find("encoder.conv_out.weight");
  const DType dt = ref != vae.end() ? ref->second.dtype : DType::F32;
  const int64_t c = 2 * latent_channels;
  auto fill = [dt](bool identity, int64_t n) {
    return [dt, identity, n](uint8_t* dst) {
      for (int64_t i = 0; i < n * (identity ? n : 1); ++i) {
        const float v = identity && i / n == i % n ? 1.0f : 0.0f;
        if (dt == DType::F32) {
          std::memcpy(dst + 4 * i, &v, 4);
        } else {
          const uint16_t h = dt == DType::F16 ? float_to_half(v) : float_to_bf16(v);
          std::memcpy(dst + 2 * i, &h, 2);
        }
      }
    };
  };
  vae["quant_conv.weight"] = {nullptr, KeyTransform::Copy, dt, {c, c, 1, 1}, fill(true, c)};
  vae["quant_conv.bias"] = {nullptr, KeyTransform::Copy, dt, {c}, fill(false, c)};
}

}  // namespace

FromOriginalReport convert_from_original(const std::string& source, const std::string& out_dir,
                                         const FromOriginalOptions& options) {
  auto weights = std::make_shared<WeightMap>(open_weights_path(source, "from-original"));
  const std::vector<std::string> keys = weights->keys();
  json cfg_unet = preset_config(options.preset, "unet");
  const json cfg_vae = preset_config(options.preset, "vae");
  const json cfg_vision = preset_config(options.preset, "image_encoder");

  OriginalLayout layout;
  layout.unet = UNetConfig::from(Config(cfg_unet, "unet/config.json"));
  layout.vae_levels = int64_t(cfg_vae["block_out_channels"].size());
  layout.has_conditioning_encoder = false;
  for (const auto& k : keys) layout.has_conditioning_encoder |= starts(k, kOrigCondEncoderPrefix);

  FromOriginalReport report;
  Plan plan;
  std::vector<std::string> unmapped, twice;
  for (const auto& k : keys) {
    const KeyMapping m = map_original_key(k, layout);
    if (m.kind == KeyMapping::Unknown) {
      unmapped.push_back(k);
      continue;
    }
    if (m.kind == KeyMapping::Dropped) {
      ++report.dropped;
      continue;
    }
    ++report.mapped;
    const StoredTensor* t = weights->find(k);
    if (!is_float_weight(t->dtype))
      throw Error(source + ": tensor " + k + " has dtype " + dtype_name(t->dtype) + ", expected F32, F16 or BF16");
    for (const auto& target : m.targets) {
      auto& slot = plan[target.component];
      if (slot.count(target.key)) twice.push_back(target.key);
      slot[target.key] = {t, target.transform, t->dtype, transformed_shape(k, t->shape, target.transform), {}};
    }
  }
  if (!layout.has_conditioning_encoder) add_identity_quant_conv(plan, cfg_vae["latent_channels"].get<int64_t>());

  // PIFR layers trained in the original naming keep their suffix (weights.md §5); their width sets text_dim.
  cfg_unet.erase("pifr");
  for (const auto& [key, p] : plan["unet"])
    if (key.find(".pifr.attn_text.to_k.weight") != std::string::npos && p.shape.size() == 2) {
      cfg_unet["pifr"] = {{"text_dim", p.shape[1]}, {"enabled", true}};
      break;
    }

  const std::vector<std::pair<std::string, json>> components = {
      {"unet", cfg_unet}, {"vae", cfg_vae}, {"image_encoder", cfg_vision}};
  std::vector<std::string> problems;
  if (!unmapped.empty())
    problems.push_back(std::to_string(unmapped.size()) + " source tensors not mapped (" + join_limited(unmapped, 8) + ")");
  if (!twice.empty()) problems.push_back("targets mapped twice (" + join_limited(twice, 8) + ")");
  std::map<std::string, std::vector<std::pair<std::string, Shape>>> expected;
  for (const auto& [folder, cfg] : components) {
    expected[folder] = component_parameters(folder, Config(cfg, folder + "/config.json"));
    std::map<std::string, StoredInfo> have;
    for (const auto& [key, p] : plan[folder]) have[key] = {p.dtype, p.shape};
    const KeyCheck c = check_keys(folder, expected[folder], have, cfg.contains("pifr"));
    if (!c.ok()) problems.push_back(c.summary(folder));
  }
  if (!problems.empty()) {
    std::string msg = source + ":";
    for (size_t i = 0; i < problems.size(); ++i) msg += (i ? "; " : " ") + problems[i];
    throw Error(msg);
  }

  const fs::path out(out_dir);
  for (const auto& [folder, cfg] : components) {
    std::vector<OutTensor> tensors;
    for (const auto& [key, shape] : expected[folder]) {
      const Planned& p = plan[folder].at(key);
      OutTensor t{key, p.dtype, p.shape, p.synth};
      if (p.source) {
        const StoredTensor* s = p.source;
        const KeyTransform tf = p.transform;
        t.fill = [s, tf](uint8_t* dst) {
          apply_transform(s->data, s->shape, dtype_size(s->dtype), tf, dst);
          release_stored(*s);  // keep resident memory small on real checkpoints
        };
      }
      tensors.push_back(std::move(t));
    }
    report.written += tensors.size();
    const fs::path dir = out / folder;
    write_weights(dir.string(), model_component(folder).stem, tensors, options.write);
    write_json_atomic((dir / "config.json").string(), cfg);
  }
  fs::create_directories(out / "scheduler");
  write_json_atomic((out / "scheduler" / "scheduler_config.json").string(), scheduler_config_json(0));
  fs::create_directories(out / "feature_extractor");
  write_json_atomic((out / "feature_extractor" / "preprocessor_config.json").string(), preprocessor_config_json());
  write_json_atomic((out / "model_index.json").string(), model_index_json(0, false, false));
  return report;
}

}  // namespace egopd
