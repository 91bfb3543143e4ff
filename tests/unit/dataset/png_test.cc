// The PNG codec (mav/dataset/png.h): bit-exact round trips, what kGreyOnly refuses and how
// kToGrey / kToBgr convert, and DataLoss / InvalidArgument / NotFound for bad input. The PNGs our
// encoder does not write (16-bit, alpha, palette) are made with libpng's simplified API.

#include "mav/dataset/png.h"

#include <png.h>

#include <cstdint>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "test_util.h"

namespace mav::dataset {
namespace {

using testing::ReadFile;
using testing::TempDir;
using testing::WriteFile;

cv::Mat RandomImage(int rows, int cols, int type, uint32_t seed) {
  cv::Mat image(rows, cols, type);
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int r = 0; r < rows; ++r) {
    uint8_t* row = image.ptr<uint8_t>(r);
    for (size_t i = 0; i < static_cast<size_t>(cols) * image.elemSize(); ++i) {
      row[i] = static_cast<uint8_t>(byte(rng));
    }
  }
  return image;
}

bool SameImage(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0;
}

// PNG bytes of `pixels` in a simplified-API `format` (16-bit samples for the linear formats),
// written by libpng itself.
std::string LibpngEncode(png_uint_32 format, int width, int height, const void* pixels,
                         const void* colormap = nullptr, png_uint_32 colormap_entries = 0) {
  png_image image;
  std::memset(&image, 0, sizeof(image));
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(width);
  image.height = static_cast<png_uint_32>(height);
  image.format = format;
  image.colormap_entries = colormap_entries;
  png_alloc_size_t size = 0;
  EXPECT_NE(png_image_write_get_memory_size(image, size, 0, pixels, 0, colormap), 0)
      << image.message;
  std::string bytes(size, '\0');
  EXPECT_NE(png_image_write_to_memory(&image, bytes.data(), &size, 0, pixels, 0, colormap), 0)
      << image.message;
  bytes.resize(size);
  return bytes;
}

uint32_t Crc32(const std::string& bytes) {
  uint32_t crc = 0xffffffffu;
  for (const unsigned char b : bytes) {
    crc ^= b;
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

void PutBigEndian(uint32_t value, std::string* bytes, size_t at) {
  for (int i = 0; i < 4; ++i) (*bytes)[at + i] = static_cast<char>(value >> (24 - 8 * i));
}

TEST(PngTest, GreyRoundTripIsBitExact) {
  const cv::Mat image = RandomImage(23, 37, CV_8UC1, 1);
  const Result<std::string> bytes = EncodePng(image);
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  for (const PngDecode mode : {PngDecode::kGreyOnly, PngDecode::kToGrey}) {
    const Result<cv::Mat> decoded = DecodePng(*bytes, mode);
    ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
    EXPECT_TRUE(decoded->isContinuous());
    EXPECT_TRUE(SameImage(*decoded, image));
  }
}

TEST(PngTest, BgrRoundTripIsBitExact) {
  const cv::Mat image = RandomImage(19, 41, CV_8UC3, 2);
  const Result<std::string> bytes = EncodePng(image);
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  const Result<cv::Mat> decoded = DecodePng(*bytes, PngDecode::kToBgr);
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  EXPECT_TRUE(SameImage(*decoded, image));
  // Blue stays in channel 0: one pure-blue pixel is no luminance-only accident.
  cv::Mat blue(1, 1, CV_8UC3, cv::Scalar(255, 0, 0));
  const Result<cv::Mat> back = DecodePng(*EncodePng(blue), PngDecode::kToBgr);
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->at<cv::Vec3b>(0, 0), cv::Vec3b(255, 0, 0));
}

TEST(PngTest, RoiOfALargerMatRoundTrips) {
  for (const int type : {CV_8UC1, CV_8UC3}) {
    const cv::Mat big = RandomImage(40, 50, type, 3);
    const cv::Mat roi = big(cv::Rect(7, 5, 21, 17));
    ASSERT_FALSE(roi.isContinuous());
    const Result<std::string> bytes = EncodePng(roi);
    ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
    const Result<cv::Mat> decoded =
        DecodePng(*bytes, type == CV_8UC1 ? PngDecode::kGreyOnly : PngDecode::kToBgr);
    ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
    EXPECT_TRUE(SameImage(*decoded, roi)) << "type " << type;
  }
}

TEST(PngTest, GreyOnlyRefusesWhatIsNotEightBitGrey) {
  const uint16_t grey16[4] = {0, 1000, 30000, 65535};
  const uint8_t grey_alpha[8] = {10, 255, 20, 128, 30, 0, 40, 255};
  const uint8_t palette[3 * 2] = {255, 0, 0, 0, 0, 255};
  const uint8_t indices[4] = {0, 1, 1, 0};
  const struct {
    std::string png;
    const char* got;
  } cases[] = {
      {*EncodePng(cv::Mat(2, 2, CV_8UC3, cv::Scalar(1, 2, 3))), "got 8-bit colour"},
      {LibpngEncode(PNG_FORMAT_LINEAR_Y, 2, 2, grey16), "got 16-bit grey"},
      {LibpngEncode(PNG_FORMAT_GA, 2, 2, grey_alpha), "got 8-bit grey with alpha"},
      {LibpngEncode(PNG_FORMAT_RGB_COLORMAP, 2, 2, indices, palette, 2), "got palette colour"},
  };
  for (const auto& c : cases) {
    const Result<cv::Mat> decoded = DecodePng(c.png, PngDecode::kGreyOnly);
    ASSERT_FALSE(decoded.ok()) << c.got;
    EXPECT_EQ(decoded.status().code(), StatusCode::kInvalidArgument);
    EXPECT_EQ(decoded.status().message(), std::string("expected an 8-bit grey image, ") + c.got);
    // kToGrey takes every one of them.
    EXPECT_TRUE(DecodePng(c.png, PngDecode::kToGrey).ok()) << c.got;
  }
}

TEST(PngTest, ToGreyConvertsColourSixteenBitAndAlpha) {
  cv::Mat bgr(1, 3, CV_8UC3);
  bgr.at<cv::Vec3b>(0, 0) = {255, 255, 255};
  bgr.at<cv::Vec3b>(0, 1) = {0, 0, 0};
  bgr.at<cv::Vec3b>(0, 2) = {128, 128, 128};
  const Result<cv::Mat> grey = DecodePng(*EncodePng(bgr), PngDecode::kToGrey);
  ASSERT_TRUE(grey.ok()) << grey.status().ToString();
  ASSERT_EQ(grey->type(), CV_8UC1);
  ASSERT_EQ(grey->size(), cv::Size(3, 1));
  EXPECT_EQ(grey->at<uint8_t>(0, 0), 255);
  EXPECT_EQ(grey->at<uint8_t>(0, 1), 0);
  EXPECT_NEAR(grey->at<uint8_t>(0, 2), 128, 1);
  // Green is brighter than blue (luminance weights, not a channel average).
  cv::Mat green_blue(1, 2, CV_8UC3);
  green_blue.at<cv::Vec3b>(0, 0) = {0, 255, 0};
  green_blue.at<cv::Vec3b>(0, 1) = {255, 0, 0};
  const Result<cv::Mat> luminance = DecodePng(*EncodePng(green_blue), PngDecode::kToGrey);
  ASSERT_TRUE(luminance.ok());
  EXPECT_GT(luminance->at<uint8_t>(0, 0), 200);
  EXPECT_LT(luminance->at<uint8_t>(0, 1), 100);

  const uint16_t grey16[2] = {65535, 0};
  const Result<cv::Mat> from16 =
      DecodePng(LibpngEncode(PNG_FORMAT_LINEAR_Y, 2, 1, grey16), PngDecode::kToGrey);
  ASSERT_TRUE(from16.ok()) << from16.status().ToString();
  EXPECT_EQ(from16->at<uint8_t>(0, 0), 255);
  EXPECT_EQ(from16->at<uint8_t>(0, 1), 0);

  // White, opaque and fully transparent: composited on black.
  const uint8_t grey_alpha[4] = {255, 255, 255, 0};
  const Result<cv::Mat> composited =
      DecodePng(LibpngEncode(PNG_FORMAT_GA, 2, 1, grey_alpha), PngDecode::kToGrey);
  ASSERT_TRUE(composited.ok()) << composited.status().ToString();
  EXPECT_EQ(composited->at<uint8_t>(0, 0), 255);
  EXPECT_EQ(composited->at<uint8_t>(0, 1), 0);
}

TEST(PngTest, ToBgrReplicatesGrey) {
  const cv::Mat image = RandomImage(3, 4, CV_8UC1, 4);
  const Result<cv::Mat> bgr = DecodePng(*EncodePng(image), PngDecode::kToBgr);
  ASSERT_TRUE(bgr.ok()) << bgr.status().ToString();
  ASSERT_EQ(bgr->type(), CV_8UC3);
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c) {
      const uint8_t v = image.at<uint8_t>(r, c);
      EXPECT_EQ(bgr->at<cv::Vec3b>(r, c), cv::Vec3b(v, v, v));
    }
  }
}

TEST(PngTest, TruncatedGarbageAndEmptyBytesAreDataLoss) {
  const std::string good = *EncodePng(RandomImage(30, 30, CV_8UC1, 5));
  const std::string inputs[] = {good.substr(0, good.size() / 2), good.substr(0, 40),
                                good.substr(0, 8), "not a png at all", ""};
  for (const std::string& bytes : inputs) {
    for (const PngDecode mode : {PngDecode::kGreyOnly, PngDecode::kToGrey}) {
      const Result<cv::Mat> decoded = DecodePng(bytes, mode);
      ASSERT_FALSE(decoded.ok()) << bytes.size() << " bytes";
      EXPECT_EQ(decoded.status().code(), StatusCode::kDataLoss) << decoded.status().ToString();
      EXPECT_EQ(decoded.status().message().rfind("cannot decode image (corrupt or truncated): ", 0),
                0u)
          << decoded.status().message();
    }
  }
}

TEST(PngTest, HugeHeaderIsRefusedBeforeAllocating) {
  // A valid 1x1 PNG whose IHDR (CRC fixed up) claims 20000 x 20000 pixels.
  std::string bytes = *EncodePng(cv::Mat(1, 1, CV_8UC1, cv::Scalar(7)));
  ASSERT_EQ(bytes.substr(12, 4), "IHDR");
  PutBigEndian(20000, &bytes, 16);
  PutBigEndian(20000, &bytes, 20);
  PutBigEndian(Crc32(bytes.substr(12, 17)), &bytes, 29);
  const Result<cv::Mat> decoded = DecodePng(bytes, PngDecode::kToGrey);
  ASSERT_FALSE(decoded.ok());
  EXPECT_EQ(decoded.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(decoded.status().message().find("20000x20000"), std::string::npos)
      << decoded.status().message();
}

TEST(PngTest, EncodeRefusesOtherTypesNamingThem) {
  const struct {
    cv::Mat image;
    const char* named;
  } cases[] = {
      {cv::Mat(4, 4, CV_16UC1, cv::Scalar(0)), "CV_16UC1"},
      {cv::Mat(4, 4, CV_8UC4, cv::Scalar(0)), "CV_8UC4"},
      {cv::Mat(4, 4, CV_32FC3, cv::Scalar(0)), "CV_32FC3"},
      {cv::Mat(), "empty"},
  };
  for (const auto& c : cases) {
    const Result<std::string> bytes = EncodePng(c.image);
    ASSERT_FALSE(bytes.ok()) << c.named;
    EXPECT_EQ(bytes.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(bytes.status().message().find(c.named), std::string::npos)
        << bytes.status().message();
  }
}

TEST(PngTest, FilesRoundTripAndErrorsNameThePath) {
  TempDir dir;
  const std::string path = dir.path() + "/image.png";
  const cv::Mat image = RandomImage(8, 9, CV_8UC1, 6);
  ASSERT_TRUE(WritePngFile(path, image).ok());
  const Result<cv::Mat> read = ReadPngFile(path, PngDecode::kGreyOnly);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  EXPECT_TRUE(SameImage(*read, image));
  EXPECT_EQ(ReadFile(path), *EncodePng(image));

  const std::string missing = dir.path() + "/missing.png";
  const Status not_found = ReadPngFile(missing, PngDecode::kToGrey).status();
  EXPECT_EQ(not_found.code(), StatusCode::kNotFound);
  EXPECT_NE(not_found.message().find(missing), std::string::npos) << not_found.message();

  WriteFile(path, "garbage");
  const Status garbage = ReadPngFile(path, PngDecode::kToGrey).status();
  EXPECT_EQ(garbage.code(), StatusCode::kDataLoss);
  EXPECT_EQ(garbage.message().rfind(path + ": ", 0), 0u) << garbage.message();

  Status written = WritePngFile(path, cv::Mat(2, 2, CV_16UC1));
  EXPECT_EQ(written.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(written.message().rfind(path + ": ", 0), 0u) << written.message();
  const std::string no_dir = dir.path() + "/no/such/dir/image.png";
  written = WritePngFile(no_dir, image);
  EXPECT_EQ(written.code(), StatusCode::kIoError);
  EXPECT_NE(written.message().find(no_dir), std::string::npos) << written.message();
}

}  // namespace
}  // namespace mav::dataset
