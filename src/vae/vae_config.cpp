#include "vae/vae_config.h"

#include <nlohmann/json.hpp>

#include "core/error.h"

namespace egopd {

VaeConfig VaeConfig::from(const Config& c) {
  VaeConfig v;
  const std::string cls = c.get_string("_class_name", "AutoencoderKLTemporalDecoder");
  if (cls != "AutoencoderKLTemporalDecoder")
    c.fail("_class_name", "'" + cls + "' is not AutoencoderKLTemporalDecoder");
  v.in_channels = c.get_int("in_channels", 3, kChannelRange);
  v.out_channels = c.get_int("out_channels", 3, kChannelRange);
  v.latent_channels = c.get_int("latent_channels", 4, kChannelRange);
  v.layers_per_block = c.get_int("layers_per_block", 1, kCountRange);
  v.block_out_channels = c.has("block_out_channels") ? c.get_int_list("block_out_channels", kChannelRange) : std::vector<int64_t>{64};
  v.scaling_factor = c.get_double("scaling_factor", 0.18215, RealRange{0, 1e3, true});
  if (v.block_out_channels.empty()) c.fail("block_out_channels", "must list at least one block");
  for (int64_t ch : v.block_out_channels)
    if (ch <= 0 || ch % kGroups != 0) c.fail("block_out_channels", "every width must be a positive multiple of 32");
  if (c.has("down_block_types")) {
    const auto types = c.get_string_list("down_block_types");
    if (types.size() != v.block_out_channels.size())
      c.fail("down_block_types", "needs one entry per block_out_channels entry");
    for (const auto& t : types)
      if (t != "DownEncoderBlock2D") c.fail("down_block_types", "'" + t + "' is not DownEncoderBlock2D");
  }
  if (v.layers_per_block < 1) c.fail("layers_per_block", "must be at least 1");
  if (v.in_channels < 1 || v.out_channels < 1 || v.latent_channels < 1)
    c.fail("latent_channels", "channel counts must be positive");
  if (!(v.scaling_factor > 0)) c.fail("scaling_factor", "must be positive");
  return v;
}

nlohmann::json VaeConfig::to_json() const {
  nlohmann::json j;
  j["_class_name"] = "AutoencoderKLTemporalDecoder";
  j["in_channels"] = in_channels;
  j["out_channels"] = out_channels;
  j["down_block_types"] = std::vector<std::string>(block_out_channels.size(), "DownEncoderBlock2D");
  j["block_out_channels"] = block_out_channels;
  j["layers_per_block"] = layers_per_block;
  j["latent_channels"] = latent_channels;
  j["scaling_factor"] = scaling_factor;
  j["force_upcast"] = true;
  return j;
}

namespace {

using ParamList = std::vector<std::pair<std::string, Shape>>;

void add_conv(ParamList& p, const std::string& name, int64_t cout, int64_t cin, int64_t k) {
  p.push_back({name + ".weight", Shape{cout, cin, k, k}});
  p.push_back({name + ".bias", Shape{cout}});
}
void add_norm(ParamList& p, const std::string& name, int64_t c) {
  p.push_back({name + ".weight", Shape{c}});
  p.push_back({name + ".bias", Shape{c}});
}
void add_resnet2d(ParamList& p, const std::string& name, int64_t cin, int64_t cout) {
  add_norm(p, name + ".norm1", cin);
  add_conv(p, name + ".conv1", cout, cin, 3);
  add_norm(p, name + ".norm2", cout);
  add_conv(p, name + ".conv2", cout, cout, 3);
  if (cin != cout) add_conv(p, name + ".conv_shortcut", cout, cin, 1);
}
void add_spatio_temporal(ParamList& p, const std::string& name, int64_t cin, int64_t cout) {
  add_resnet2d(p, name + ".spatial_res_block", cin, cout);
  const std::string t = name + ".temporal_res_block";
  add_norm(p, t + ".norm1", cout);
  p.push_back({t + ".conv1.weight", Shape{cout, cout, 3, 1, 1}});
  p.push_back({t + ".conv1.bias", Shape{cout}});
  add_norm(p, t + ".norm2", cout);
  p.push_back({t + ".conv2.weight", Shape{cout, cout, 3, 1, 1}});
  p.push_back({t + ".conv2.bias", Shape{cout}});
  p.push_back({name + ".time_mixer.mix_factor", Shape{1}});
}
void add_attention(ParamList& p, const std::string& name, int64_t c) {
  add_norm(p, name + ".group_norm", c);
  for (const char* l : {"to_q", "to_k", "to_v", "to_out.0"}) {
    p.push_back({name + "." + l + ".weight", Shape{c, c}});
    p.push_back({name + "." + l + ".bias", Shape{c}});
  }
}

}  // namespace

std::vector<std::pair<std::string, Shape>> vae_parameter_shapes(const VaeConfig& cfg) {
  ParamList p;
  const auto& boc = cfg.block_out_channels;
  const int64_t n = cfg.levels(), L = cfg.layers_per_block, top = boc.back();
  // encoder
  add_conv(p, "encoder.conv_in", boc[0], cfg.in_channels, 3);
  int64_t prev = boc[0];
  for (int64_t i = 0; i < n; ++i) {
    const std::string b = "encoder.down_blocks." + std::to_string(i);
    for (int64_t j = 0; j < L; ++j)
      add_resnet2d(p, b + ".resnets." + std::to_string(j), j == 0 ? prev : boc[i], boc[i]);
    if (i + 1 < n) add_conv(p, b + ".downsamplers.0.conv", boc[i], boc[i], 3);
    prev = boc[i];
  }
  add_resnet2d(p, "encoder.mid_block.resnets.0", top, top);
  add_attention(p, "encoder.mid_block.attentions.0", top);
  add_resnet2d(p, "encoder.mid_block.resnets.1", top, top);
  add_norm(p, "encoder.conv_norm_out", top);
  add_conv(p, "encoder.conv_out", 2 * cfg.latent_channels, top, 3);
  add_conv(p, "quant_conv", 2 * cfg.latent_channels, 2 * cfg.latent_channels, 1);
  // decoder
  add_conv(p, "decoder.conv_in", top, cfg.latent_channels, 3);
  for (int64_t j = 0; j < L; ++j) add_spatio_temporal(p, "decoder.mid_block.resnets." + std::to_string(j), top, top);
  add_attention(p, "decoder.mid_block.attentions.0", top);
  prev = top;
  for (int64_t i = 0; i < n; ++i) {
    const int64_t c = boc[n - 1 - i];
    const std::string b = "decoder.up_blocks." + std::to_string(i);
    for (int64_t j = 0; j <= L; ++j)
      add_spatio_temporal(p, b + ".resnets." + std::to_string(j), j == 0 ? prev : c, c);
    if (i + 1 < n) add_conv(p, b + ".upsamplers.0.conv", c, c, 3);
    prev = c;
  }
  add_norm(p, "decoder.conv_norm_out", boc[0]);
  add_conv(p, "decoder.conv_out", cfg.out_channels, boc[0], 3);
  p.push_back({"decoder.time_conv_out.weight", Shape{cfg.out_channels, cfg.out_channels, 3, 1, 1}});
  p.push_back({"decoder.time_conv_out.bias", Shape{cfg.out_channels}});
  return p;
}

namespace {

double conv_flop(int64_t cin, int64_t cout, int64_t k, int64_t out_pixels) {
  return 2.0 * double(cin) * double(cout) * double(k * k) * double(out_pixels);
}
double resnet_flop(int64_t cin, int64_t cout, int64_t hw) {
  return conv_flop(cin, cout, 3, hw) + conv_flop(cout, cout, 3, hw) + (cin != cout ? conv_flop(cin, cout, 1, hw) : 0.0);
}
double attention_flop(int64_t c, int64_t hw) {
  return 4 * 2.0 * double(hw) * double(c) * double(c) + 2 * 2.0 * double(hw) * double(hw) * double(c);
}

}  // namespace

double vae_encode_flop(const VaeConfig& cfg, int64_t frames, int64_t height, int64_t width) {
  const auto& boc = cfg.block_out_channels;
  int64_t h = height, w = width;
  double f = conv_flop(cfg.in_channels, boc[0], 3, h * w);
  int64_t prev = boc[0];
  for (int64_t i = 0; i < cfg.levels(); ++i) {
    for (int64_t j = 0; j < cfg.layers_per_block; ++j) f += resnet_flop(j == 0 ? prev : boc[i], boc[i], h * w);
    if (i + 1 < cfg.levels()) {
      h = (h + 1 - 3) / 2 + 1;
      w = (w + 1 - 3) / 2 + 1;
      f += conv_flop(boc[i], boc[i], 3, h * w);
    }
    prev = boc[i];
  }
  const int64_t top = boc.back();
  f += 2 * resnet_flop(top, top, h * w) + attention_flop(top, h * w);
  f += conv_flop(top, 2 * cfg.latent_channels, 3, h * w) +
       conv_flop(2 * cfg.latent_channels, 2 * cfg.latent_channels, 1, h * w);
  return f * double(frames);
}

double vae_decode_flop(const VaeConfig& cfg, int64_t frames, int64_t latent_h, int64_t latent_w) {
  const auto& boc = cfg.block_out_channels;
  const int64_t n = cfg.levels(), top = boc.back();
  int64_t hw = latent_h * latent_w;
  auto st_block = [&](int64_t cin, int64_t cout) { return resnet_flop(cin, cout, hw) + 2 * 2.0 * 3.0 * cout * cout * hw; };
  double f = conv_flop(cfg.latent_channels, top, 3, hw);
  f += st_block(top, top);
  if (cfg.layers_per_block >= 2) f += attention_flop(top, hw) + st_block(top, top);
  int64_t prev = top;
  for (int64_t i = 0; i < n; ++i) {
    const int64_t c = boc[n - 1 - i];
    for (int64_t j = 0; j <= cfg.layers_per_block; ++j) f += st_block(j == 0 ? prev : c, c);
    if (i + 1 < n) {
      hw *= 4;
      f += conv_flop(c, c, 3, hw);
    }
    prev = c;
  }
  f += conv_flop(boc[0], cfg.out_channels, 3, hw) + 2.0 * 3.0 * cfg.out_channels * cfg.out_channels * hw;
  return f * double(frames);
}

}  // namespace egopd
