#include "core/golden.h"

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/safetensors.h"

namespace egopd {
namespace fs = std::filesystem;

std::string GoldenCase::model_dir() const {
  return (fs::path(dir) / spec.get_string("model_dir", "model")).string();
}

const Tensor& GoldenCase::input(const std::string& n) const {
  auto it = inputs.find(n);
  if (it == inputs.end()) throw Error("case " + name + ": input tensor '" + n + "' is missing from inputs.safetensors");
  return it->second;
}

GoldenCase load_golden_case(const std::string& dir) {
  GoldenCase c;
  c.dir = dir;
  c.spec = Config::load((fs::path(dir) / "case.json").string());
  c.name = c.spec.get_string("name", fs::path(dir).filename().string());
  c.component = c.spec.get_string("component");
  c.args = c.spec.has("args") ? c.spec.sub("args") : Config(nlohmann::json::object(), c.spec.source() + ":args");
  if (c.spec.has("inputs")) {
    SafeTensorsFile f((fs::path(dir) / c.spec.get_string("inputs")).string());
    for (const auto& t : f.tensors()) {
      if (is_float_weight(t.dtype)) {
        c.inputs[t.name] = t.to_f32().reshaped(t.shape.empty() ? Shape{1} : Shape(t.shape));
      } else {
        c.id_inputs[t.name] = IdTensor{Shape(t.shape), t.to_i64()};
      }
    }
  }
  return c;
}

void write_case_outputs(const std::string& path, const CaseOutputs& out) {
  std::vector<TensorToWrite> w;
  for (const auto& [n, t] : out.tensors) w.push_back(to_write(n, t));
  for (const auto& [n, t] : out.ids) w.push_back(to_write(n, t));
  write_safetensors(path, w);
}

std::vector<CompareRow> compare_case_outputs(const GoldenCase& c, const CaseOutputs& out) {
  SafeTensorsFile exp((fs::path(c.dir) / c.spec.get_string("expected", "expected.safetensors")).string());
  const auto& tol = c.spec.json()["tolerance"];
  std::vector<CompareRow> rows;
  for (auto it = tol.begin(); it != tol.end(); ++it) {
    CompareRow r;
    r.name = it.key();
    r.tol_max_abs = (*it).value("max_abs", 0.0);
    r.tol_rel_l2 = (*it).value("rel_l2", 0.0);
    const StoredTensor* e = exp.find(r.name);
    if (!e) throw Error(c.dir + ": expected.safetensors lacks " + r.name);
    const std::vector<int64_t> eshape = e->shape;
    if (e->dtype == DType::I64 || e->dtype == DType::I32) {
      auto ids = out.ids.find(r.name);
      if (ids == out.ids.end()) {
        r.message = "MISSING";
      } else if (ids->second.shape.vec() != eshape) {
        r.message = "shape " + ids->second.shape.str() + " != expected " + e->shape_str();
      } else {
        std::vector<int64_t> ev = e->to_i64();
        int64_t bad = 0;
        for (size_t i = 0; i < ev.size(); ++i) bad += ev[i] != ids->second.values[i];
        r.ok = bad == 0;
        r.message = std::to_string(bad) + " of " + std::to_string(ev.size()) + " ids differ";
      }
      rows.push_back(r);
      continue;
    }
    auto t = out.tensors.find(r.name);
    if (t == out.tensors.end()) {
      r.message = "MISSING";
      rows.push_back(r);
      continue;
    }
    if (t->second.shape().vec() != eshape) {
      r.message = "shape " + t->second.shape().str() + " != expected " + e->shape_str();
      rows.push_back(r);
      continue;
    }
    Tensor ev = e->to_f32();
    double nd = 0, nb = 0, mx = 0;
    bool finite = true;
    for (int64_t i = 0; i < ev.numel(); ++i) {
      double a = t->second[i], b = ev[i];
      if (!std::isfinite(a)) finite = false;
      double d = a - b;
      mx = std::max(mx, std::fabs(d));
      nd += d * d;
      nb += b * b;
    }
    r.max_abs = mx;
    r.rel_l2 = nb > 0 ? std::sqrt(nd) / std::sqrt(nb) : std::sqrt(nd);
    if (!finite) {
      r.message = "non-finite values";
    } else {
      r.ok = r.max_abs <= r.tol_max_abs && r.rel_l2 <= r.tol_rel_l2;
    }
    rows.push_back(r);
  }
  return rows;
}

}  // namespace egopd
