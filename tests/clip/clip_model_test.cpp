// CLIP towers on tiny random models written here, against a double-precision forward written in this test (quick_gelu,
// legacy and explicit EOS pooling, text projection, nested CLIPConfig), and strict weight loading errors.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "clip_image/clip_vision.h"
#include "clip_text/clip_text.h"
#include "core/error.h"
#include "core/safetensors.h"

namespace egopd {
namespace {

namespace fs = std::filesystem;
using Vec = std::vector<double>;

// ---- double-precision reference -------------------------------------------------------------------------------

struct Param {
  std::vector<int64_t> shape;
  std::vector<float> values;
};
using Params = std::map<std::string, Param>;

// x [rows, in] -> [rows, out] with W [out, in] (+ b)
Vec linear(const Vec& x, int64_t rows, const Params& P, const std::string& name, bool bias = true) {
  const Param& w = P.at(name + ".weight");
  const int64_t out = w.shape[0], in = w.shape[1];
  Vec y(static_cast<size_t>(rows * out));
  for (int64_t r = 0; r < rows; ++r)
    for (int64_t o = 0; o < out; ++o) {
      double acc = bias ? P.at(name + ".bias").values[size_t(o)] : 0.0;
      for (int64_t i = 0; i < in; ++i) acc += x[size_t(r * in + i)] * w.values[size_t(o * in + i)];
      y[size_t(r * out + o)] = acc;
    }
  return y;
}

Vec layer_norm(const Vec& x, int64_t rows, const Params& P, const std::string& name, double eps = 1e-5) {
  const Param& g = P.at(name + ".weight");
  const int64_t c = int64_t(g.values.size());
  Vec y(x.size());
  for (int64_t r = 0; r < rows; ++r) {
    double mean = 0, var = 0;
    for (int64_t i = 0; i < c; ++i) mean += x[size_t(r * c + i)];
    mean /= double(c);
    for (int64_t i = 0; i < c; ++i) var += (x[size_t(r * c + i)] - mean) * (x[size_t(r * c + i)] - mean);
    var /= double(c);
    for (int64_t i = 0; i < c; ++i)
      y[size_t(r * c + i)] = (x[size_t(r * c + i)] - mean) / std::sqrt(var + eps) * g.values[size_t(i)] +
                             P.at(name + ".bias").values[size_t(i)];
  }
  return y;
}

double activation(double x, bool quick) {
  return quick ? x / (1 + std::exp(-1.702 * x)) : 0.5 * x * (1 + std::erf(x / std::sqrt(2.0)));
}

// One sequence h [len, d] through encoder.layers.N (clip.md §1).
void reference_layer(Vec& h, int64_t len, int64_t d, int64_t heads, bool quick, bool causal, const Params& P,
                     const std::string& pre) {
  const Vec x1 = layer_norm(h, len, P, pre + "layer_norm1");
  const Vec q = linear(x1, len, P, pre + "self_attn.q_proj"), k = linear(x1, len, P, pre + "self_attn.k_proj"),
            v = linear(x1, len, P, pre + "self_attn.v_proj");
  const int64_t dh = d / heads;
  Vec attn(static_cast<size_t>(len * d), 0.0);
  for (int64_t hd = 0; hd < heads; ++hd)
    for (int64_t i = 0; i < len; ++i) {
      Vec s(static_cast<size_t>(len));
      double mx = -1e300;
      for (int64_t j = 0; j < len; ++j) {
        double dot = 0;
        for (int64_t c = 0; c < dh; ++c) dot += q[size_t(i * d + hd * dh + c)] * k[size_t(j * d + hd * dh + c)];
        s[size_t(j)] = (causal && j > i) ? -1e300 : dot / std::sqrt(double(dh));
        mx = std::max(mx, s[size_t(j)]);
      }
      double z = 0;
      for (auto& e : s) z += (e = (e <= -1e299 ? 0.0 : std::exp(e - mx)));
      for (int64_t j = 0; j < len; ++j)
        for (int64_t c = 0; c < dh; ++c)
          attn[size_t(i * d + hd * dh + c)] += s[size_t(j)] / z * v[size_t(j * d + hd * dh + c)];
    }
  const Vec o = linear(attn, len, P, pre + "self_attn.out_proj");
  for (size_t i = 0; i < h.size(); ++i) h[i] += o[i];
  Vec m = linear(layer_norm(h, len, P, pre + "layer_norm2"), len, P, pre + "mlp.fc1");
  for (auto& e : m) e = activation(e, quick);
  const Vec f = linear(m, len, P, pre + "mlp.fc2");
  for (size_t i = 0; i < h.size(); ++i) h[i] += f[i];
}

// ---- tiny models on disk --------------------------------------------------------------------------------------

class TinyModelDir : public ::testing::Test {
 protected:
  fs::path dir = fs::temp_directory_path() / ("egopd-clip-" + std::to_string(::getpid()) + "-" +
                                              ::testing::UnitTest::GetInstance()->current_test_info()->name());
  std::mt19937 rng{42};
  Params params;

  void SetUp() override { fs::create_directories(dir); }
  void TearDown() override { fs::remove_all(dir); }

  void add(const std::string& name, std::vector<int64_t> shape, double scale = 0.5, double offset = 0.0) {
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    Param p{shape, {}};
    int64_t n = 1;
    for (int64_t s : shape) n *= s;
    for (int64_t i = 0; i < n; ++i) p.values.push_back(float(offset + scale * u(rng)));
    params[name] = p;
  }
  void add_layer_norm(const std::string& name, int64_t c) {
    add(name + ".weight", {c}, 0.2, 1.0);
    add(name + ".bias", {c}, 0.1);
  }
  void add_encoder(const std::string& pre, int64_t layers, int64_t d, int64_t inter) {
    for (int64_t l = 0; l < layers; ++l) {
      const std::string p = pre + "encoder.layers." + std::to_string(l) + ".";
      add_layer_norm(p + "layer_norm1", d);
      add_layer_norm(p + "layer_norm2", d);
      for (const char* proj : {"q_proj", "k_proj", "v_proj", "out_proj"}) {
        add(p + "self_attn." + proj + ".weight", {d, d}, 1.0 / std::sqrt(double(d)));
        add(p + "self_attn." + proj + ".bias", {d}, 0.1);
      }
      add(p + "mlp.fc1.weight", {inter, d}, 1.0 / std::sqrt(double(d)));
      add(p + "mlp.fc1.bias", {inter}, 0.1);
      add(p + "mlp.fc2.weight", {d, inter}, 1.0 / std::sqrt(double(inter)));
      add(p + "mlp.fc2.bias", {d}, 0.1);
    }
  }
  void write(const std::string& config_json, const Params& extra = {}) {
    std::ofstream(dir / "config.json") << config_json;
    std::vector<TensorToWrite> t;
    for (const Params* set : {static_cast<const Params*>(&params), &extra})
      for (const auto& [name, p] : *set) t.push_back(to_write(name, Tensor::from(Shape(p.shape), p.values)));
    write_safetensors((dir / "model.safetensors").string(), t);
  }
  std::string load_error_text(bool vision) {
    try {
      if (vision)
        ClipVisionModelWithProjection::load_dir(dir.string());
      else
        ClipTextModel::load_dir(dir.string());
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  }
};

// Text tower: hidden 16, 2 heads, 2 layers, vocab 50, 9 positions.
class TinyText : public TinyModelDir {
 protected:
  static constexpr int64_t d = 16, heads = 2, layers = 2, inter = 40, vocab = 50, positions = 9, proj = 6;
  void SetUp() override {
    TinyModelDir::SetUp();
    add("text_model.embeddings.token_embedding.weight", {vocab, d});
    add("text_model.embeddings.position_embedding.weight", {positions, d});
    add_encoder("text_model.", layers, d, inter);
    add_layer_norm("text_model.final_layer_norm", d);
  }
  std::string config(const std::string& act, int64_t eos) const {
    return R"({"hidden_size": 16, "intermediate_size": 40, "num_attention_heads": 2, "num_hidden_layers": 2,
      "vocab_size": 50, "max_position_embeddings": 9, "hidden_act": ")" +
           act + R"(", "layer_norm_eps": 1e-05,
      "eos_token_id": )" +
           std::to_string(eos) + R"(, "projection_dim": 6})";
  }
  // last_hidden_state [len, d] of one sequence.
  Vec reference(const std::vector<int64_t>& ids, bool quick) const {
    const int64_t len = int64_t(ids.size());
    Vec h(static_cast<size_t>(len * d));
    for (int64_t i = 0; i < len; ++i)
      for (int64_t c = 0; c < d; ++c)
        h[size_t(i * d + c)] =
            double(params.at("text_model.embeddings.token_embedding.weight").values[size_t(ids[size_t(i)] * d + c)]) +
            params.at("text_model.embeddings.position_embedding.weight").values[size_t(i * d + c)];
    for (int64_t l = 0; l < layers; ++l)
      reference_layer(h, len, d, heads, quick, /*causal=*/true, params,
                      "text_model.encoder.layers." + std::to_string(l) + ".");
    return layer_norm(h, len, params, "text_model.final_layer_norm");
  }
};

void expect_close(const float* got, const Vec& want, size_t n, double tol, const std::string& what) {
  double worst = 0;
  for (size_t i = 0; i < n; ++i) worst = std::max(worst, std::fabs(double(got[i]) - want[i]));
  EXPECT_LT(worst, tol) << what;
}

TEST_F(TinyText, QuickGeluLegacyArgmaxPoolingAndProjection) {
  add("text_projection.weight", {proj, d}, 0.3);
  write(config("quick_gelu", 2));
  const ClipTextModel model = ClipTextModel::load_dir(dir.string());
  ASSERT_TRUE(model.has_projection());
  const std::vector<int64_t> row0 = {48, 5, 7, 49, 0, 0, 0}, row1 = {48, 49, 49, 3, 1, 2, 49};
  IdTensor ids{Shape{2, 7}, row0};
  ids.values.insert(ids.values.end(), row1.begin(), row1.end());
  const ClipTextOutput out = model.forward(ids);
  ASSERT_EQ(out.last_hidden_state.shape(), (Shape{2, 7, d}));
  for (int r = 0; r < 2; ++r) {
    const Vec ref = reference(r ? row1 : row0, /*quick=*/true);
    expect_close(out.last_hidden_state.data() + r * 7 * d, ref, size_t(7 * d), 2e-5, "last_hidden_state");
    // Legacy eos_token_id 2: the first occurrence of the largest id (49 at position 3, resp. 1).
    const int64_t pos = r ? 1 : 3;
    const Vec pooled(ref.begin() + pos * d, ref.begin() + (pos + 1) * d);
    expect_close(out.pooler_output.data() + r * d, pooled, size_t(d), 2e-5, "pooler_output");
    const Vec emb = linear(pooled, 1, params, "text_projection", /*bias=*/false);
    expect_close(out.text_embeds.data() + r * proj, emb, size_t(proj), 2e-5, "text_embeds");
  }
}

TEST_F(TinyText, GeluAndFirstEosPoolingWithCausalPrefixInvariance) {
  write(config("gelu", 7));
  const ClipTextModel model = ClipTextModel::load_dir(dir.string());
  EXPECT_FALSE(model.has_projection());
  const std::vector<int64_t> a = {48, 7, 9, 7, 30}, b = {48, 7, 9, 7, 11, 12, 13, 14, 15};
  const ClipTextOutput oa = model.forward(IdTensor{Shape{1, 5}, a});
  const ClipTextOutput ob = model.forward(IdTensor{Shape{1, 9}, b});
  const Vec ref = reference(a, /*quick=*/false);
  expect_close(oa.last_hidden_state.data(), ref, size_t(5 * d), 2e-5, "last_hidden_state");
  expect_close(oa.pooler_output.data(), Vec(ref.begin() + d, ref.begin() + 2 * d), size_t(d), 2e-5, "pooled at 1");
  // Causality: tokens after position 3 never change positions 0..3.
  for (int64_t i = 0; i < 4 * d; ++i) EXPECT_NEAR(oa.last_hidden_state[i], ob.last_hidden_state[i], 1e-6);
  // No EOS in the row: position 0.
  const ClipTextOutput none = model.forward(IdTensor{Shape{1, 3}, {1, 2, 3}});
  for (int64_t c = 0; c < d; ++c) EXPECT_EQ(none.pooler_output[c], none.last_hidden_state[c]);
  EXPECT_THROW(model.forward(IdTensor{Shape{1, 10}, std::vector<int64_t>(10, 1)}), Error);  // > 9 positions
  EXPECT_THROW(model.forward(IdTensor{Shape{1, 2}, {1, 50}}), Error);                       // outside vocab
}

TEST_F(TinyText, MissingMisShapedAndUnexpectedKeys) {
  params.erase("text_model.encoder.layers.1.mlp.fc1.bias");
  write(config("gelu", 7));
  std::string e = load_error_text(false);
  EXPECT_NE(e.find("text_model.encoder.layers.1.mlp.fc1.bias"), std::string::npos) << e;
  EXPECT_NE(e.find("[40]"), std::string::npos) << e;

  add("text_model.encoder.layers.1.mlp.fc1.bias", {41});
  write(config("gelu", 7));
  e = load_error_text(false);
  EXPECT_NE(e.find("text_model.encoder.layers.1.mlp.fc1.bias"), std::string::npos) << e;
  EXPECT_NE(e.find("[41]"), std::string::npos) << e;
  EXPECT_NE(e.find("[40]"), std::string::npos) << e;

  add("text_model.encoder.layers.1.mlp.fc1.bias", {40});
  write(config("gelu", 7), {{"text_model.encoder.layers.2.mlp.fc1.bias", {{40}, std::vector<float>(40, 0.f)}}});
  e = load_error_text(false);
  EXPECT_NE(e.find("unexpected tensor text_model.encoder.layers.2.mlp.fc1.bias"), std::string::npos) << e;

  // Tolerated extras: buffers, logit_scale, the image tower of a full CLIPModel file.
  write(config("gelu", 7), {{"text_model.embeddings.position_ids", {{1, 9}, std::vector<float>(9, 0.f)}},
                            {"logit_scale", {{1}, {2.6f}}},
                            {"visual_projection.weight", {{6, 16}, std::vector<float>(96, 0.f)}},
                            {"vision_model.post_layernorm.weight", {{16}, std::vector<float>(16, 1.f)}}});
  EXPECT_EQ(load_error_text(false), "");

  write(config("relu", 7));
  e = load_error_text(false);
  EXPECT_NE(e.find("hidden_act"), std::string::npos) << e;
}

// Vision tower: 28x28 images, patch 14 (4 patches), hidden 12, 3 heads, 1 layer, projection 5.
class TinyVision : public TinyModelDir {
 protected:
  static constexpr int64_t d = 12, heads = 3, inter = 24, patch = 14, image = 28, proj = 5, seq = 5;
  void SetUp() override {
    TinyModelDir::SetUp();
    add("vision_model.embeddings.class_embedding", {d});
    add("vision_model.embeddings.patch_embedding.weight", {d, 3, patch, patch}, 0.05);
    add("vision_model.embeddings.position_embedding.weight", {seq, d});
    add_layer_norm("vision_model.pre_layrnorm", d);
    add_encoder("vision_model.", 1, d, inter);
    add_layer_norm("vision_model.post_layernorm", d);
    add("visual_projection.weight", {proj, d}, 0.3);
  }
};

TEST_F(TinyVision, NestedClipConfigMatchesReference) {
  // A full CLIPConfig: the vision fields nested, projection_dim at the top level.
  write(R"({"model_type": "clip", "projection_dim": 5, "text_config": {"hidden_size": 99},
    "vision_config": {"hidden_size": 12, "intermediate_size": 24, "num_attention_heads": 3, "num_hidden_layers": 1,
    "image_size": 28, "patch_size": 14, "hidden_act": "quick_gelu", "layer_norm_eps": 1e-05}})",
        {{"text_projection.weight", {{5, 99}, std::vector<float>(495, 0.f)}}});
  const ClipVisionModelWithProjection model = ClipVisionModelWithProjection::load_dir(dir.string());
  Tensor px({2, 3, image, image});
  std::uniform_real_distribution<float> u(-2.f, 2.f);
  for (int64_t i = 0; i < px.numel(); ++i) px[i] = u(rng);
  const ClipVisionOutput out = model.forward(px);
  ASSERT_EQ(out.last_hidden_state.shape(), (Shape{2, seq, d}));
  ASSERT_EQ(out.image_embeds.shape(), (Shape{2, proj}));

  const Param& w = params.at("vision_model.embeddings.patch_embedding.weight");
  for (int64_t b = 0; b < 2; ++b) {
    // Tokens: class embedding, then the 2x2 patches in raster order; plus position embeddings.
    Vec h(static_cast<size_t>(seq * d));
    for (int64_t t = 0; t < seq; ++t)
      for (int64_t o = 0; o < d; ++o) {
        double acc = 0;
        if (t == 0) {
          acc = params.at("vision_model.embeddings.class_embedding").values[size_t(o)];
        } else {
          const int64_t py = (t - 1) / 2, pxi = (t - 1) % 2;
          for (int64_t c = 0; c < 3; ++c)
            for (int64_t i = 0; i < patch; ++i)
              for (int64_t j = 0; j < patch; ++j)
                acc += double(w.values[size_t(((o * 3 + c) * patch + i) * patch + j)]) *
                       px[((b * 3 + c) * image + py * patch + i) * image + pxi * patch + j];
        }
        h[size_t(t * d + o)] =
            acc + params.at("vision_model.embeddings.position_embedding.weight").values[size_t(t * d + o)];
      }
    h = layer_norm(h, seq, params, "vision_model.pre_layrnorm");
    reference_layer(h, seq, d, heads, /*quick=*/true, /*causal=*/false, params, "vision_model.encoder.layers.0.");
    expect_close(out.last_hidden_state.data() + b * seq * d, h, size_t(seq * d), 2e-5, "last_hidden_state");
    const Vec pooled = layer_norm(Vec(h.begin(), h.begin() + d), 1, params, "vision_model.post_layernorm");
    expect_close(out.pooler_output.data() + b * d, pooled, size_t(d), 2e-5, "pooler_output");
    expect_close(out.image_embeds.data() + b * proj, linear(pooled, 1, params, "visual_projection", false),
                 size_t(proj), 2e-5, "image_embeds");
  }
  EXPECT_THROW(model.forward(Tensor::zeros({1, 3, 14, 14})), Error);  // position embeddings fix the image size
}

TEST_F(TinyVision, MissingProjectionIsAnErrorNamingTheKey) {
  params.erase("visual_projection.weight");
  write(R"({"hidden_size": 12, "intermediate_size": 24, "num_attention_heads": 3, "num_hidden_layers": 1,
    "image_size": 28, "patch_size": 14, "projection_dim": 5, "hidden_act": "gelu"})");
  const std::string e = load_error_text(true);
  EXPECT_NE(e.find("missing tensor visual_projection.weight"), std::string::npos) << e;
  EXPECT_NE(e.find("[5,12]"), std::string::npos) << e;
}

TEST_F(TinyVision, BadGeometryInConfigIsAnError) {
  write(R"({"hidden_size": 12, "intermediate_size": 24, "num_attention_heads": 5, "num_hidden_layers": 1,
    "image_size": 28, "patch_size": 14, "projection_dim": 5})");
  EXPECT_NE(load_error_text(true).find("num_attention_heads"), std::string::npos);
  write(R"({"hidden_size": 12, "intermediate_size": 24, "num_attention_heads": 3, "num_hidden_layers": 1,
    "image_size": 30, "patch_size": 14, "projection_dim": 5})");
  EXPECT_NE(load_error_text(true).find("patch_size"), std::string::npos);
}

}  // namespace
}  // namespace egopd
