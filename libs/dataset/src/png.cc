#include "mav/dataset/png.h"

#include <png.h>

#include <cstring>
#include <limits>

#include <opencv2/core.hpp>

#include "mav/common/file.h"

namespace mav::dataset {
namespace {

// Owns libpng's state of one simplified-API call. png_image_free is safe after the API has
// freed the state itself (it does on every write and on every failure), so the destructor
// always calls it: no early return can leak it.
class PngImage {
 public:
  PngImage() {
    std::memset(&image_, 0, sizeof(image_));
    image_.version = PNG_IMAGE_VERSION;
  }
  ~PngImage() { png_image_free(&image_); }
  PngImage(const PngImage&) = delete;
  PngImage& operator=(const PngImage&) = delete;

  png_image* get() { return &image_; }
  std::string message() const {
    return image_.message[0] != '\0' ? std::string(image_.message) : "libpng gave no reason";
  }

 private:
  png_image image_;
};

// What a file holds, from the format png_image_begin_read_* reports: "16-bit grey",
// "8-bit colour with alpha", "palette colour".
std::string DescribeFormat(png_uint_32 format) {
  std::string text;
  if ((format & PNG_FORMAT_FLAG_COLORMAP) != 0) {
    text = "palette";
  } else {
    text = (format & PNG_FORMAT_FLAG_LINEAR) != 0 ? "16-bit" : "8-bit";
  }
  text += (format & PNG_FORMAT_FLAG_COLOR) != 0 ? " colour" : " grey";
  if ((format & PNG_FORMAT_FLAG_ALPHA) != 0) text += " with alpha";
  return text;
}

Status CheckPixelCount(int64_t width, int64_t height) {
  if (width * height <= kMaxPngPixels) return Status::Ok();
  return Status::InvalidArgument("image is " + std::to_string(width) + "x" +
                                 std::to_string(height) + ", over the limit of " +
                                 std::to_string(kMaxPngPixels) + " pixels");
}

Status DecodeError(const PngImage& png) {
  return Status::DataLoss("cannot decode image (corrupt or truncated): " + png.message());
}

}  // namespace

Result<cv::Mat> DecodePng(std::string_view bytes, PngDecode mode) {
  if (bytes.empty()) return Status::DataLoss("cannot decode image (corrupt or truncated): empty");
  PngImage png;
  png_image& image = *png.get();
  if (png_image_begin_read_from_memory(&image, bytes.data(), bytes.size()) == 0) {
    return DecodeError(png);
  }
  // Both factors are below 2^32: the product fits in int64_t. Checked before anything is
  // allocated, and it bounds rows and cols far below INT_MAX.
  MAV_RETURN_IF_ERROR(CheckPixelCount(image.width, image.height));
  if (mode == PngDecode::kGreyOnly && image.format != PNG_FORMAT_GRAY) {
    return Status::InvalidArgument("expected an 8-bit grey image, got " +
                                   DescribeFormat(image.format));
  }
  const bool bgr = mode == PngDecode::kToBgr;
  image.format = bgr ? PNG_FORMAT_BGR : PNG_FORMAT_GRAY;
  cv::Mat decoded(static_cast<int>(image.height), static_cast<int>(image.width),
                  bgr ? CV_8UC3 : CV_8UC1);
  // Alpha, if any, is composited on this colour (grey output uses its green).
  const png_color black{0, 0, 0};
  if (png_image_finish_read(&image, &black, decoded.data, static_cast<png_int_32>(decoded.step[0]),
                            nullptr) == 0) {
    return DecodeError(png);
  }
  return decoded;
}

Result<std::string> EncodePng(const cv::Mat& image) {
  if (image.empty() || image.dims != 2) {
    return Status::InvalidArgument(
        "expected a non-empty 2-D image, got " +
        (image.empty() ? std::string("an empty one") : std::to_string(image.dims) + " dimensions"));
  }
  if (image.type() != CV_8UC1 && image.type() != CV_8UC3) {
    return Status::InvalidArgument("expected a CV_8UC1 (grey) or CV_8UC3 (BGR) image, got " +
                                   cv::typeToString(image.type()));
  }
  MAV_RETURN_IF_ERROR(CheckPixelCount(image.cols, image.rows));
  if (image.step[0] > static_cast<size_t>(std::numeric_limits<png_int_32>::max())) {
    return Status::InvalidArgument("row stride of " + std::to_string(image.step[0]) +
                                   " bytes is beyond libpng's range");
  }
  const auto row_stride = static_cast<png_int_32>(image.step[0]);  // 1-byte components
  PngImage png;
  png_image& header = *png.get();
  header.width = static_cast<png_uint_32>(image.cols);
  header.height = static_cast<png_uint_32>(image.rows);
  header.format = image.type() == CV_8UC1 ? PNG_FORMAT_GRAY : PNG_FORMAT_BGR;
  // No row filters and zlib level 3: on mav-sim's 752x480 grey images 7.6 ms and 280 kB an image
  // instead of 27 ms and 199 kB (OpenCV's imencode, zlib level 1 with RLE: 3.2 ms, 234 kB).
  // Data sets are written once and read many times, the case libpng documents this flag for.
  header.flags = PNG_IMAGE_FLAG_FAST;
  // One compression pass into a buffer of libpng's upper bound on the PNG size, rather than a
  // size query that compresses the image twice. With at most kMaxPngPixels * 3 bytes the bound's
  // 32-bit arithmetic cannot overflow. libpng frees its state after each write, so the same
  // header serves a second call should the bound ever be short: then the failed call reported
  // the size it needs.
  std::string bytes;
  png_alloc_size_t size = PNG_IMAGE_PNG_SIZE_MAX(header);
  for (int attempt = 0; attempt < 2; ++attempt) {
    const png_alloc_size_t capacity = size;
    bytes.resize(capacity);
    if (png_image_write_to_memory(&header, bytes.data(), &size, /*convert_to_8_bit=*/0, image.data,
                                  row_stride, /*colormap=*/nullptr) != 0) {
      bytes.resize(size);
      return bytes;
    }
    if (size <= capacity) break;  // a real failure: libpng left the size alone
  }
  return Status::Internal("PNG encoding failed: " + png.message());
}

Result<cv::Mat> ReadPngFile(const std::string& path, PngDecode mode) {
  MAV_ASSIGN_OR_RETURN(const std::string bytes, ReadFileToString(path));
  Result<cv::Mat> image = DecodePng(bytes, mode);
  if (!image.ok()) return image.status().WithContext(path);
  return image;
}

Status WritePngFile(const std::string& path, const cv::Mat& image) {
  Result<std::string> bytes = EncodePng(image);
  if (!bytes.ok()) return bytes.status().WithContext(path);
  return WriteStringToFileAtomic(path, *bytes);
}

}  // namespace mav::dataset
