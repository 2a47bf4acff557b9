#pragma once
// Video / image I/O of the prediction commands (egopressurediff.md §1): clip and mask loading with uniform frame
// sampling and the S x S squash, the procedural sample clip of the built-in demo, and atomic PNG / MP4 writers.
// Frames are kept as 8-bit OpenCV images (RGB order) so the same pixels feed the model and the side-by-side video.
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "core/tensor.h"

namespace egopd {

// round(linspace(0, n - 1, count)) with round-half-to-even like numpy; count >= 1, n >= 1.
std::vector<int64_t> uniform_frame_indices(int64_t n, int64_t count);

// File-name order by frame number: runs of digits compare as numbers (2.png before 10.png, frame_9 before
// frame_10), everything else character by character.
bool natural_less(const std::string& a, const std::string& b);
// Image files of a folder (png, jpg, jpeg, bmp, tif, tiff, webp; case-insensitive) in natural_less order of names.
std::vector<std::string> list_image_files(const std::string& dir);

// The files whose name (without extension) ends in `suffix`, e.g. "_rgb" for the data release's 00005_rgb.png.
std::vector<std::string> files_with_stem_suffix(const std::vector<std::string>& files, const std::string& suffix);

// Resizes to size x size ignoring the aspect ratio, antialiased: INTER_AREA along an axis that shrinks,
// INTER_LINEAR along one that grows (each axis handled on its own when one shrinks and the other grows).
cv::Mat squash_to_square(const cv::Mat& img, int size);

struct LoadedClip {
  std::vector<cv::Mat> rgb;              // `frames` images, size x size, CV_8UC3 in RGB order
  std::vector<int64_t> source_indices;  // index of each sampled frame in the source
  int64_t source_frames = 0;            // frames in the video / images in the folder
};
// A video file (OpenCV VideoCapture) or a folder of images; samples `frames` frames uniformly over the clip. A
// folder holding *_rgb images (the data release's layout, beside *_mask and *_pressure images) uses only those.
// Errors (one line): missing path, unreadable video or image, zero frames.
LoadedClip load_clip(const std::string& path, int64_t frames, int size);
// Source frames already in memory (8-bit RGB, CV_8UC3, any one size; the images are only read): sampled and squashed
// exactly as the images of a frame folder are.
LoadedClip clip_from_images(const std::vector<cv::Mat>& rgb, int64_t frames, int size);

// 8-bit RGB images -> [F, 3, S, S] float32 with x = 2 (v / 255) - 1.
Tensor frames_to_tensor(const std::vector<cv::Mat>& rgb);

// A folder of mask images -> [F, 1, S, S] in {0, 1} (grey value > 127 is hand; nearest-neighbour resize), F =
// clip.source_indices.size(). It holds either one mask per sampled frame (in name order) or one per source frame
// (the dataset layout: masks beside every frame), of which the sampled ones are taken. Any other count is an error.
// A folder holding *_mask images uses only those.
Tensor load_masks(const std::string& dir, const LoadedClip& clip, int size);
// Masks already in memory (8-bit grey, CV_8UC1), counted and used like the images of a mask folder; `what` names
// them in errors.
Tensor masks_from_images(const std::vector<cv::Mat>& grey, const LoadedClip& clip, int size, const std::string& what);

// The built-in demo clip, deterministic: a skin-coloured hand-like blob closing its fingers around a coloured box
// over a plain background. `frames` RGB images of size x size.
std::vector<cv::Mat> synthetic_sample_clip(int frames, int size);

// Atomic writers (temporary file in the same folder, then rename). Images are given in BGR order (OpenCV's).
void write_png_atomic(const std::string& path, const cv::Mat& bgr);
// MPEG-4 Part 2 ('mp4v') at `fps`; every frame must have the same size.
void write_video_atomic(const std::string& path, const std::vector<cv::Mat>& bgr, double fps);

}  // namespace egopd
