#include "pipeline/media.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <functional>
#include <system_error>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <opencv2/videoio/registry.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/safetensors.h"

namespace egopd {
namespace fs = std::filesystem;

std::vector<int64_t> uniform_frame_indices(int64_t n, int64_t count) {
  if (n < 1 || count < 1) throw Error("frame sampling needs at least one frame");
  std::vector<int64_t> idx(size_t(count), 0);
  if (count == 1) return idx;
  // Same arithmetic as numpy.linspace (start + i * step) followed by numpy.round (half to even, the default
  // floating-point rounding mode of nearbyint).
  const double step = double(n - 1) / double(count - 1);
  for (int64_t i = 0; i < count; ++i) idx[size_t(i)] = int64_t(std::nearbyint(double(i) * step));
  idx.back() = n - 1;  // numpy sets the endpoint exactly
  return idx;
}

bool natural_less(const std::string& a, const std::string& b) {
  size_t i = 0, j = 0;
  const auto digit = [](char c) { return c >= '0' && c <= '9'; };
  while (i < a.size() && j < b.size()) {
    if (digit(a[i]) && digit(b[j])) {  // compare the numbers: leading zeros dropped, then length, then digits
      size_t ie = i, je = j;
      while (ie < a.size() && digit(a[ie])) ++ie;
      while (je < b.size() && digit(b[je])) ++je;
      size_t is = i, js = j;
      while (is + 1 < ie && a[is] == '0') ++is;
      while (js + 1 < je && b[js] == '0') ++js;
      if (ie - is != je - js) return ie - is < je - js;
      const int c = a.compare(is, ie - is, b, js, je - js);
      if (c != 0) return c < 0;
      i = ie, j = je;
    } else {
      if (a[i] != b[j]) return a[i] < b[j];
      ++i, ++j;
    }
  }
  if ((i < a.size()) != (j < b.size())) return j < b.size();  // a is a prefix of b
  return a < b;  // equal as numbers (e.g. 5 and 05): any fixed order
}

std::vector<std::string> list_image_files(const std::string& dir) {
  static const char* const kExt[] = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp"};
  std::vector<std::string> files;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (!e.is_regular_file()) continue;
    std::string ext = e.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    for (const char* k : kExt)
      if (ext == k) files.push_back(e.path().string());
  }
  if (ec) throw Error(dir + ": cannot list folder (" + ec.message() + ")");
  std::sort(files.begin(), files.end(), [](const std::string& a, const std::string& b) {
    return natural_less(fs::path(a).filename().string(), fs::path(b).filename().string());
  });
  return files;
}

std::vector<std::string> files_with_stem_suffix(const std::vector<std::string>& files, const std::string& suffix) {
  std::vector<std::string> out;
  for (const std::string& f : files) {
    const std::string stem = fs::path(f).stem().string();
    if (stem.size() >= suffix.size() && stem.compare(stem.size() - suffix.size(), suffix.size(), suffix) == 0)
      out.push_back(f);
  }
  return out;
}

// The images of a folder, or only those named *<suffix> when there are any.
static std::vector<std::string> role_files(const std::string& dir, const std::string& suffix) {
  std::vector<std::string> files = list_image_files(dir);
  std::vector<std::string> role = files_with_stem_suffix(files, suffix);
  return role.empty() ? files : role;
}

cv::Mat squash_to_square(const cv::Mat& img, int size) {
  const auto interp = [](int from, int to) { return to < from ? cv::INTER_AREA : cv::INTER_LINEAR; };
  cv::Mat out;
  if (img.cols == size && img.rows == size) return img.clone();
  const bool shrink_x = size < img.cols, shrink_y = size < img.rows;
  if (shrink_x == shrink_y || img.cols == size || img.rows == size) {
    const int ix = img.cols == size ? interp(img.rows, size) : interp(img.cols, size);
    cv::resize(img, out, cv::Size(size, size), 0, 0, ix);
    return out;
  }
  // One axis shrinks, the other grows: INTER_AREA would act like nearest-neighbour on the growing axis.
  cv::Mat tmp;
  cv::resize(img, tmp, cv::Size(size, img.rows), 0, 0, interp(img.cols, size));
  cv::resize(tmp, out, cv::Size(size, size), 0, 0, interp(img.rows, size));
  return out;
}

static cv::Mat to_rgb8(const cv::Mat& bgr, const std::string& source) {
  if (bgr.empty()) throw Error(source + ": cannot decode image");
  cv::Mat m = bgr;
  if (m.depth() != CV_8U) {  // 16-bit PNG/TIFF: scale to 8 bits
    cv::Mat c;
    m.convertTo(c, CV_8U, m.depth() == CV_16U ? 1.0 / 257.0 : 255.0);
    m = c;
  }
  cv::Mat rgb;
  if (m.channels() == 1) cv::cvtColor(m, rgb, cv::COLOR_GRAY2RGB);
  else if (m.channels() == 4) cv::cvtColor(m, rgb, cv::COLOR_BGRA2RGB);
  else cv::cvtColor(m, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

static LoadedClip load_folder(const std::string& dir, int64_t frames, int size) {
  const std::vector<std::string> files = role_files(dir, "_rgb");
  if (files.empty()) throw Error(dir + ": folder holds no images (png, jpg, jpeg, bmp, tif, tiff, webp)");
  LoadedClip c;
  c.source_frames = int64_t(files.size());
  c.source_indices = uniform_frame_indices(c.source_frames, frames);
  for (int64_t i : c.source_indices) {
    const std::string& f = files[size_t(i)];
    c.rgb.push_back(squash_to_square(to_rgb8(cv::imread(f, cv::IMREAD_UNCHANGED), f), size));
  }
  return c;
}

// FFmpeg when OpenCV has it: the GStreamer backend (tried first by CAP_ANY on some builds) floods stderr with
// critical messages for files it cannot play, and its frame counting differs.
static int video_backend() {
  return cv::videoio_registry::hasBackend(cv::CAP_FFMPEG) ? int(cv::CAP_FFMPEG) : int(cv::CAP_ANY);
}

static LoadedClip load_video(const std::string& path, int64_t frames, int size) {
  // Two passes: count the frames by grabbing them (the container's frame count is often wrong), then decode only
  // the sampled ones, so a long clip never sits in memory.
  cv::VideoCapture cap(path, video_backend());
  if (!cap.isOpened()) throw Error(path + ": cannot open video (unsupported format or not a video)");
  int64_t n = 0;
  while (cap.grab()) ++n;
  if (n == 0) throw Error(path + ": video has zero readable frames");
  LoadedClip c;
  c.source_frames = n;
  c.source_indices = uniform_frame_indices(n, frames);
  cap.release();
  if (!cap.open(path, video_backend())) throw Error(path + ": cannot reopen video");
  int64_t pos = 0;
  cv::Mat bgr;
  for (int64_t want : c.source_indices) {
    // Sampled indices repeat when the clip is shorter than F: reuse the last decoded frame.
    if (want < pos && !bgr.empty()) {
      c.rgb.push_back(c.rgb.back().clone());
      continue;
    }
    for (; pos < want; ++pos)
      if (!cap.grab()) throw Error(path + ": video ended early while seeking frame " + std::to_string(want));
    if (!cap.read(bgr)) throw Error(path + ": cannot decode frame " + std::to_string(want));
    ++pos;
    c.rgb.push_back(squash_to_square(to_rgb8(bgr, path), size));
  }
  return c;
}

LoadedClip clip_from_images(const std::vector<cv::Mat>& rgb, int64_t frames, int size) {
  if (frames < 1) throw Error("--frames must be at least 1");
  if (rgb.empty()) throw Error("no frames given");
  LoadedClip c;
  c.source_frames = int64_t(rgb.size());
  c.source_indices = uniform_frame_indices(c.source_frames, frames);
  for (int64_t i : c.source_indices) {
    const cv::Mat& m = rgb[size_t(i)];
    if (m.empty() || m.type() != CV_8UC3) throw Error("frames must be non-empty 8-bit RGB images");
    c.rgb.push_back(squash_to_square(m, size));
  }
  return c;
}

LoadedClip load_clip(const std::string& path, int64_t frames, int size) {
  if (frames < 1) throw Error("--frames must be at least 1");
  if (!fs::exists(path)) throw Error(path + ": no such video file or frame folder");
  return fs::is_directory(path) ? load_folder(path, frames, size) : load_video(path, frames, size);
}

Tensor frames_to_tensor(const std::vector<cv::Mat>& rgb) {
  if (rgb.empty()) throw Error("no frames");
  const int64_t F = int64_t(rgb.size()), H = rgb[0].rows, W = rgb[0].cols, plane = H * W;
  Tensor t({F, 3, H, W});
  for (int64_t f = 0; f < F; ++f) {
    const cv::Mat& m = rgb[size_t(f)];
    if (m.rows != H || m.cols != W || m.type() != CV_8UC3) throw Error("frames must share one size and be 8-bit RGB");
    float* dst = t.data() + f * 3 * plane;
    for (int64_t y = 0; y < H; ++y) {
      const uint8_t* row = m.ptr<uint8_t>(int(y));
      for (int64_t x = 0; x < W; ++x)
        for (int64_t ch = 0; ch < 3; ++ch) dst[ch * plane + y * W + x] = 2.0f * (float(row[x * 3 + ch]) / 255.0f) - 1.0f;
    }
  }
  return t;
}

// One mask per sampled frame or one per source frame of `clip`; image(i) gives the i-th of `count` grey images.
static Tensor masks_tensor(size_t count, const std::function<cv::Mat(size_t)>& image, const LoadedClip& clip, int size,
                           const std::string& what) {
  const int64_t frames = int64_t(clip.source_indices.size());
  const bool per_source_frame = int64_t(count) == clip.source_frames;
  if (!per_source_frame && int64_t(count) != frames)
    throw Error(what + ": " + std::to_string(count) + " mask images but " + std::to_string(frames) +
                " sampled frames of " + std::to_string(clip.source_frames) +
                " (give one mask per sampled frame or one per frame of the clip)");
  const int64_t plane = int64_t(size) * size;
  Tensor t({frames, 1, size, size});
  for (int64_t f = 0; f < frames; ++f) {
    const cv::Mat g = image(size_t(per_source_frame ? clip.source_indices[size_t(f)] : f));
    cv::Mat r;
    cv::resize(g, r, cv::Size(size, size), 0, 0, cv::INTER_NEAREST);
    float* dst = t.data() + f * plane;
    for (int y = 0; y < size; ++y) {
      const uint8_t* row = r.ptr<uint8_t>(y);
      for (int x = 0; x < size; ++x) dst[int64_t(y) * size + x] = row[x] > 127 ? 1.0f : 0.0f;
    }
  }
  return t;
}

Tensor load_masks(const std::string& dir, const LoadedClip& clip, int size) {
  if (!fs::is_directory(dir)) throw Error(dir + ": mask folder does not exist");
  const std::vector<std::string> files = role_files(dir, "_mask");
  const auto image = [&](size_t i) {
    cv::Mat g = cv::imread(files[i], cv::IMREAD_GRAYSCALE);
    if (g.empty()) throw Error(files[i] + ": cannot decode mask image");
    return g;
  };
  return masks_tensor(files.size(), image, clip, size, dir);
}

Tensor masks_from_images(const std::vector<cv::Mat>& grey, const LoadedClip& clip, int size, const std::string& what) {
  for (const cv::Mat& m : grey)
    if (m.empty() || m.type() != CV_8UC1) throw Error(what + ": masks must be non-empty 8-bit grey images");
  return masks_tensor(grey.size(), [&](size_t i) { return grey[i]; }, clip, size, what);
}

std::vector<cv::Mat> synthetic_sample_clip(int frames, int size) {
  // Drawn at 256 x 256 in BGR and resized, so every size shows the same scene.
  const int S = 256;
  const cv::Scalar background(214, 222, 226), table(150, 170, 186), box(60, 70, 200), box_top(90, 110, 230);
  const cv::Scalar skin(128, 160, 222), skin_dark(100, 130, 190);
  std::vector<cv::Mat> out;
  for (int f = 0; f < frames; ++f) {
    const double t = frames > 1 ? double(f) / double(frames - 1) : 1.0;  // 0: open hand far away, 1: grasp
    cv::Mat img(S, S, CV_8UC3, background);
    cv::rectangle(img, cv::Point(0, 190), cv::Point(S, S), table, cv::FILLED);
    cv::rectangle(img, cv::Point(104, 130), cv::Point(160, 196), box, cv::FILLED, cv::LINE_AA);
    cv::rectangle(img, cv::Point(104, 122), cv::Point(160, 134), box_top, cv::FILLED, cv::LINE_AA);
    // The hand approaches from the lower right, then the fingers curl towards the box.
    const double approach = std::min(1.0, t / 0.6), close = std::max(0.0, (t - 0.6) / 0.4);
    const cv::Point palm(int(std::lround(230 - 50 * approach)), int(std::lround(230 - 60 * approach)));
    cv::ellipse(img, palm, cv::Size(30, 36), -30, 0, 360, skin, cv::FILLED, cv::LINE_AA);
    for (int k = 0; k < 4; ++k) {
      const double base = -150 + 22 * k;  // finger direction in degrees (towards the upper left)
      const double angle = (base - 40 * close) * CV_PI / 180.0;
      const double len = 44 - 10 * close;
      const cv::Point root(palm.x + int(std::lround(22 * std::cos(angle))), palm.y + int(std::lround(22 * std::sin(angle))));
      const cv::Point tip(root.x + int(std::lround(len * std::cos(angle))), root.y + int(std::lround(len * std::sin(angle))));
      cv::line(img, root, tip, skin, 13, cv::LINE_AA);
      cv::circle(img, tip, 6, skin_dark, cv::FILLED, cv::LINE_AA);
    }
    const double ta = (150 + 30 * close) * CV_PI / 180.0;  // thumb swings under the box
    const cv::Point troot(palm.x - 8, palm.y + 20);
    cv::line(img, troot, cv::Point(troot.x + int(std::lround(40 * std::cos(ta))), troot.y + int(std::lround(40 * std::sin(ta)))),
             skin, 14, cv::LINE_AA);
    cv::Mat rgb;
    cv::cvtColor(img, rgb, cv::COLOR_BGR2RGB);
    out.push_back(squash_to_square(rgb, size));
  }
  return out;
}

void write_png_atomic(const std::string& path, const cv::Mat& bgr) {
  std::vector<uint8_t> buf;
  if (!cv::imencode(".png", bgr, buf)) throw Error(path + ": PNG encoding failed");
  write_file_atomic(path, buf.data(), buf.size());
}

void write_video_atomic(const std::string& path, const std::vector<cv::Mat>& bgr, double fps) {
  if (bgr.empty()) throw Error(path + ": no frames to write");
  for (const cv::Mat& m : bgr)
    if (m.size() != bgr[0].size()) throw Error(path + ": video frames differ in size");
  const fs::path p(path);
  // The temporary name keeps the .mp4 extension: OpenCV picks the container from it.
  std::string name = ".";  // appended piecewise: GCC 12 warns (-Wrestrict, falsely) on the chained operator+
  name += p.stem().string();
  name += ".tmp" + std::to_string(::getpid()) + ".mp4";
  const fs::path tmp = p.parent_path() / name;
  struct RemoveOnFailure {
    fs::path file;
    bool keep = false;
    ~RemoveOnFailure() {
      std::error_code ec;
      if (!keep) fs::remove(file, ec);
    }
  } guard{tmp};
  {
    cv::VideoWriter w(tmp.string(), video_backend(), cv::VideoWriter::fourcc('m', 'p', '4', 'v'), fps, bgr[0].size(),
                      true);
    if (!w.isOpened()) throw Error(path + ": cannot open an MPEG-4 video writer (OpenCV built without a video backend?)");
    for (const cv::Mat& m : bgr) w.write(m);
    w.release();
  }
  // OpenCV's writer reports no I/O errors (a full disk truncates the file silently): read the frame count back.
  std::error_code ec;
  if (!fs::exists(tmp) || fs::file_size(tmp, ec) == 0) throw Error(path + ": video writer produced no file");
  int64_t written = 0;
  {
    cv::VideoCapture r(tmp.string(), video_backend());
    cv::Mat frame;
    while (r.isOpened() && r.read(frame)) ++written;
  }
  if (written != int64_t(bgr.size()))
    throw Error(path + ": video writer stored " + std::to_string(written) + " of " + std::to_string(bgr.size()) +
                " frames (disk full or write error)");
  fs::rename(tmp, p, ec);
  if (ec) throw Error(path + ": cannot move the video into place (" + ec.message() + ")");
  guard.keep = true;
}

}  // namespace egopd
