#pragma once
// Golden test cases (case.json + model/ + inputs.safetensors + expected.safetensors): loading, and the same
// comparison compare.py makes (max_abs and rel_l2 against the case's tolerances; ids exactly).
#include <map>
#include <string>
#include <vector>

#include "core/config.h"
#include "core/tensor.h"

namespace egopd {

struct GoldenCase {
  std::string dir;
  std::string name, component;
  Config spec;                               // the whole case.json
  Config args;                               // case.json "args"
  std::map<std::string, Tensor> inputs;      // float inputs (F32/F16/BF16 converted)
  std::map<std::string, IdTensor> id_inputs; // I64/I32 inputs
  std::string model_dir() const;             // dir/model (or case.json model_dir)

  const Tensor& input(const std::string& name) const;  // error naming the case and tensor if absent
  bool has_input(const std::string& name) const { return inputs.count(name) != 0; }
};

GoldenCase load_golden_case(const std::string& dir);

struct CaseOutputs {
  std::map<std::string, Tensor> tensors;
  std::map<std::string, IdTensor> ids;
};

// Writes every output to one safetensors file (atomically).
void write_case_outputs(const std::string& path, const CaseOutputs& out);

struct CompareRow {
  std::string name;
  bool ok = false;
  double max_abs = 0, rel_l2 = 0, tol_max_abs = 0, tol_rel_l2 = 0;
  std::string message;  // shape mismatch, missing, non-finite, ids differing
};
// Compares with expected.safetensors exactly as compare.py does.
std::vector<CompareRow> compare_case_outputs(const GoldenCase& c, const CaseOutputs& out);

}  // namespace egopd
