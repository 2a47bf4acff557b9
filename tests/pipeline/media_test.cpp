// Clip / mask loading (egopressurediff.md §1): uniform sampling, folder order, RGB order, scaling to [-1, 1],
// mask binarisation and count checks, the video round trip, and the prediction commands' option parsing.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "pipeline/media.h"
#include "pipeline/predict_run.h"

namespace egopd {
namespace {
namespace fs = std::filesystem;

struct TempDir {
  fs::path path;
  TempDir() {
    path = fs::temp_directory_path() / ("egopd_media_test_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() { fs::remove_all(path); }
  std::string operator/(const std::string& n) const { return (path / n).string(); }
};

TEST(Media, UniformFrameIndices) {
  using V = std::vector<int64_t>;
  EXPECT_EQ(uniform_frame_indices(10, 4), (V{0, 3, 6, 9}));
  EXPECT_EQ(uniform_frame_indices(5, 4), (V{0, 1, 3, 4}));
  EXPECT_EQ(uniform_frame_indices(3, 5), (V{0, 0, 1, 2, 2}));  // 0.5 -> 0, 1.5 -> 2: half to even like numpy
  EXPECT_EQ(uniform_frame_indices(1, 3), (V{0, 0, 0}));
  EXPECT_EQ(uniform_frame_indices(48, 1), (V{0}));
  const V all = uniform_frame_indices(16, 16);
  for (int64_t i = 0; i < 16; ++i) EXPECT_EQ(all[size_t(i)], i);
  EXPECT_EQ(uniform_frame_indices(46, 16).back(), 45);
  EXPECT_THROW(uniform_frame_indices(0, 4), Error);
}

TEST(Media, SquashKeepsUniformColourAndSize) {
  for (cv::Size s : {cv::Size(100, 50), cv::Size(300, 200), cv::Size(20, 30), cv::Size(64, 64)}) {
    cv::Mat img(s, CV_8UC3, cv::Scalar(10, 120, 250));
    cv::Mat out = squash_to_square(img, 64);
    ASSERT_EQ(out.rows, 64);
    ASSERT_EQ(out.cols, 64);
    EXPECT_EQ(out.at<cv::Vec3b>(31, 17), cv::Vec3b(10, 120, 250));
  }
}

TEST(Media, LoadsFolderSortedSampledAndScaled) {
  TempDir d;
  // Names sort differently from creation order; a non-image file is ignored.
  for (int i = 4; i >= 0; --i) {
    cv::Mat bgr(40, 60, CV_8UC3, cv::Scalar(0, 50 * i, 255));  // B, G, R
    ASSERT_TRUE(cv::imwrite(d / ("frame_" + std::to_string(i) + ".png"), bgr));
  }
  std::ofstream(d / "notes.txt") << "not an image";
  const LoadedClip c = load_clip(d.path.string(), 3, 64);
  EXPECT_EQ(c.source_frames, 5);
  EXPECT_EQ(c.source_indices, (std::vector<int64_t>{0, 2, 4}));
  ASSERT_EQ(c.rgb.size(), 3u);
  EXPECT_EQ(c.rgb[1].at<cv::Vec3b>(10, 10), cv::Vec3b(255, 100, 0));  // RGB order, frame_2
  const Tensor t = frames_to_tensor(c.rgb);
  ASSERT_EQ(t.shape().str(), Shape({3, 3, 64, 64}).str());
  const int64_t plane = 64 * 64;
  EXPECT_FLOAT_EQ(t.data()[2 * 3 * plane + 0 * plane + 5], 1.0f);                      // R = 255
  EXPECT_FLOAT_EQ(t.data()[2 * 3 * plane + 1 * plane + 5], 2.0f * (200.0f / 255.0f) - 1);  // G = 200
  EXPECT_FLOAT_EQ(t.data()[2 * 3 * plane + 2 * plane + 5], -1.0f);                     // B = 0
}

// A clip of `source` frames of which `frames` are sampled uniformly (no pixels: only the indices matter to masks).
LoadedClip sampled(int64_t frames, int64_t source) {
  LoadedClip c;
  c.source_frames = source;
  c.source_indices = uniform_frame_indices(source, frames);
  return c;
}

TEST(Media, FramesInFrameNumberOrder) {
  EXPECT_TRUE(natural_less("2.png", "10.png"));
  EXPECT_FALSE(natural_less("10.png", "2.png"));
  EXPECT_TRUE(natural_less("frame_9.jpg", "frame_10.jpg"));
  EXPECT_TRUE(natural_less("00005_rgb.png", "00010_rgb.png"));
  EXPECT_TRUE(natural_less("a.png", "b.png"));
  EXPECT_TRUE(natural_less("x1", "x1a"));
  EXPECT_FALSE(natural_less("7.png", "7.png"));
  EXPECT_NE(natural_less("5.png", "05.png"), natural_less("05.png", "5.png"));  // a strict order even then
  TempDir d;
  for (const char* name : {"10.png", "2.png", "1.png", "100.png"}) {
    cv::Mat m(4, 4, CV_8UC3, cv::Scalar(0, 0, 0));
    ASSERT_TRUE(cv::imwrite(d / name, m));
  }
  std::vector<std::string> names;
  for (const std::string& f : list_image_files(d.path.string())) names.push_back(fs::path(f).filename().string());
  EXPECT_EQ(names, (std::vector<std::string>{"1.png", "2.png", "10.png", "100.png"}));
}

TEST(Media, LoadErrors) {
  TempDir d;
  EXPECT_THROW(load_clip(d / "missing.mp4", 4, 64), Error);
  EXPECT_THROW(load_clip(d.path.string(), 4, 64), Error);  // folder without images
  std::ofstream(d / "fake.mp4") << "not a video";
  EXPECT_THROW(load_clip(d / "fake.mp4", 4, 64), Error);
  EXPECT_THROW(load_masks(d / "no_masks", sampled(2, 2), 64), Error);
}

TEST(Media, MasksBinarisedAndCounted) {
  TempDir d;
  for (int i = 0; i < 3; ++i) {
    cv::Mat m(32, 32, CV_8UC1, cv::Scalar(0));
    m(cv::Rect(0, 0, 16, 32)).setTo(200);
    m(cv::Rect(16, 0, 16, 32)).setTo(i == 0 ? 127 : 128);  // > 127 is hand
    ASSERT_TRUE(cv::imwrite(d / ("m" + std::to_string(i) + ".png"), m));
  }
  const Tensor m = load_masks(d.path.string(), sampled(3, 10), 64);
  ASSERT_EQ(m.shape().str(), Shape({3, 1, 64, 64}).str());
  EXPECT_EQ(m.data()[10], 1.0f);
  EXPECT_EQ(m.data()[40], 0.0f);             // frame 0, right half: 127
  EXPECT_EQ(m.data()[64 * 64 + 40], 1.0f);  // frame 1, right half: 128
  try {
    load_masks(d.path.string(), sampled(4, 10), 64);
    FAIL() << "mask count mismatch accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("3 mask images but 4 sampled frames of 10"), std::string::npos) << e.what();
  }
}

// The dataset layout: a mask beside every frame of the clip; the masks of the sampled frames are taken.
TEST(Media, MasksOfEverySourceFrameAreSampled) {
  TempDir d;
  for (int i = 0; i < 5; ++i) {
    cv::Mat m(8, 8, CV_8UC1, cv::Scalar(i % 2 == 0 ? 255 : 0));  // frames 0, 2, 4 all hand; 1, 3 none
    ASSERT_TRUE(cv::imwrite(d / ("m" + std::to_string(i) + ".png"), m));
  }
  const Tensor m = load_masks(d.path.string(), sampled(3, 5), 8);  // source indices 0, 2, 4
  ASSERT_EQ(m.shape().str(), Shape({3, 1, 8, 8}).str());
  for (int64_t i = 0; i < m.numel(); ++i) ASSERT_EQ(m.data()[i], 1.0f) << i;
  const Tensor two = load_masks(d.path.string(), sampled(2, 5), 8);  // source indices 0, 4
  for (int64_t i = 0; i < two.numel(); ++i) ASSERT_EQ(two.data()[i], 1.0f) << i;
}

TEST(Media, VideoRoundTrip) {
  TempDir d;
  std::vector<cv::Mat> bgr;
  for (const cv::Mat& m : synthetic_sample_clip(8, 64)) {
    cv::Mat b;
    cv::cvtColor(m, b, cv::COLOR_RGB2BGR);
    bgr.push_back(b);
  }
  write_video_atomic(d / "clip.mp4", bgr, 5);
  const LoadedClip c = load_clip(d / "clip.mp4", 4, 64);
  EXPECT_EQ(c.source_frames, 8);
  EXPECT_EQ(c.source_indices, (std::vector<int64_t>{0, 2, 5, 7}));
  ASSERT_EQ(c.rgb.size(), 4u);
  // Lossy codec: the background colour survives approximately (RGB 226, 222, 214).
  const cv::Vec3b px = c.rgb[0].at<cv::Vec3b>(4, 4);
  EXPECT_NEAR(px[0], 226, 12);
  EXPECT_NEAR(px[2], 214, 12);
  for (const auto& e : fs::directory_iterator(d.path)) EXPECT_EQ(e.path().filename().string()[0] != '.', true);
}

TEST(Media, SampleClipIsDeterministicAndMoves) {
  const auto a = synthetic_sample_clip(4, 64), b = synthetic_sample_clip(4, 64);
  ASSERT_EQ(a.size(), 4u);
  EXPECT_EQ(cv::norm(a[3], b[3], cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a[0], a[3], cv::NORM_L1), 0.0);
}

TEST(PredictOptions, Parsing) {
  EXPECT_EQ(parse_guidance("1,3"), std::make_pair(1.0f, 3.0f));
  EXPECT_EQ(parse_guidance("2.5"), std::make_pair(2.5f, 2.5f));
  for (const char* bad : {"", "1,", ",3", "1,2,3", "a,b", "1;3", "-1,2"}) EXPECT_THROW(parse_guidance(bad), Error) << bad;
  const VarySpec v = parse_vary("weight=1,355,omit");
  EXPECT_EQ(v.field, "weight");
  EXPECT_EQ(v.values, (std::vector<std::string>{"1", "355", "omit"}));
  EXPECT_THROW(parse_vary("weight"), Error);
  EXPECT_THROW(parse_vary("colour=red"), Error);
  EXPECT_THROW(parse_vary("weight=1,,2"), Error);
  EXPECT_EQ(variant_folder_name("weight", "355g"), "weight_355g");
  EXPECT_EQ(variant_folder_name("obj_name", "a Coca/Cola can"), "obj_name_a_Coca_Cola_can");
  EXPECT_EQ(variant_folder_name("bodyfat", "25%"), "bodyfat_25pct");
  PredictOptions o;
  EXPECT_EQ(resolve_steps(o, "euler"), 0);
  o.sampler = "lcm";
  EXPECT_EQ(resolve_steps(o, "euler"), 4);  // student setting on a teacher model
  EXPECT_EQ(resolve_steps(o, "animatelcm"), 0);
  o.steps = 6;
  EXPECT_EQ(resolve_steps(o, "euler"), 6);
}

}  // namespace
}  // namespace egopd
