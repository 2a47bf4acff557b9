#pragma once
// Dataset manifests: one JSON object per line, one clip each, read by `egopd batch` and `egopd evaluate
// --manifest` and written by `egopd manifest` (or by hand). Fields:
//   id      (required) folder name of the clip's outputs: letters, digits, '.', '_', '-'; unique; not starting '.'
//   frames  (required) a video file or a folder of frames (a folder with *_rgb.* frames uses only those)
//   masks   folder of hint masks (one per sampled frame, or one per frame of the clip; *_mask.* only if present)
//   meta    object of prompt fields (obj_name, weight, material, gender, age, subj_weight, bodyfat), or
//   prompt  the prompt verbatim (not both)
//   gt      ground truth: a taxel CSV (raw glove readings in N, frame = index in the clip) or a folder of
//           pressure heatmaps (*_pressure.*, one per frame of the clip)
//   split   a split name or a list of them (e.g. "object_held_out")
// Relative paths are relative to the manifest's folder. Errors name the file, line and field.
#include <optional>
#include <string>
#include <vector>

#include "pipeline/predict_run.h"

namespace egopd {

struct ManifestClip {
  std::string id;
  std::string frames;  // resolved paths
  std::string masks;
  std::optional<PromptFields> meta;
  std::optional<std::string> prompt;
  std::string gt;
  std::vector<std::string> splits;
  int line = 0;  // 1-based line in the manifest file

  ClipSource source() const { return ClipSource{frames, masks, prompt, meta, {}, {}}; }
};

struct Manifest {
  std::string path;
  std::vector<ManifestClip> clips;  // in file order
};

Manifest read_manifest(const std::string& path);
// One clip -> one JSON line (no newline). Paths are written as given.
std::string manifest_line(const ManifestClip& c);

// `egopd manifest`: one clip per sequence folder of a dataset tree (see manifest_builder.cpp for the layout and
// the attribute file), written atomically to `out`; paths in it are relative to out's folder when possible.
struct ManifestBuildOptions {
  std::string root;
  std::string list;        // motion_list.txt; empty: root/motion_list.txt if present, else every sequence folder
  std::string attributes;  // attribute file (JSON); empty: no meta, no splits
  std::string out;
};
// Returns the number of clips written.
size_t build_manifest(const ManifestBuildOptions& o);

}  // namespace egopd
