#pragma once
// PNG images in memory and on disk, on libpng's simplified API (libpng 1.6). The one image codec
// of the stack: OpenCV's imgcodecs would pull GDAL and ~100 MB of GIS libraries into the
// container image.
//
// Decoding refuses images over kMaxPngPixels before it allocates anything, so a hostile header
// cannot make us allocate unbounded memory. Pixel values are not gamma-converted for the files we
// write (they carry an sRGB chunk) nor for files without gamma information; a file whose gAMA
// chunk says another gamma (1.0, say) is converted to sRGB, as libpng's simplified API always
// does (OpenCV's decoder ignored gAMA).

#include <cstdint>
#include <string>
#include <string_view>

#include <opencv2/core/mat.hpp>

#include "mav/common/status.h"

namespace mav::dataset {

// 2^28 pixels (16384 x 16384): far above any camera or plot, and at most 256 MB per channel.
inline constexpr int64_t kMaxPngPixels = int64_t{1} << 28;

enum class PngDecode {
  // Only an 8-bit single-channel grey PNG (1-, 2- and 4-bit grey are widened to 8 bits); colour,
  // palette, alpha and 16-bit images are refused with InvalidArgument naming what the file holds
  // ("expected an 8-bit grey image, got 16-bit grey"). For data sets, where a colour image is a
  // mistake, not something to convert.
  kGreyOnly,
  // Any PNG, converted to 8-bit grey by libpng: colour to luminance (sRGB weights 0.2126 R +
  // 0.7152 G + 0.0722 B), alpha composited on black, 16 bits reduced to 8. For a user's image
  // given to a client.
  kToGrey,
  // Any PNG, converted to 8-bit BGR (OpenCV's channel order): grey replicated, alpha composited
  // on black, 16 bits reduced to 8. For reading back a plot.
  kToBgr,
};

// A continuous CV_8UC1 image (CV_8UC3 with kToBgr). DataLoss for empty, corrupt or truncated bytes
// (the message carries libpng's); InvalidArgument for an image over kMaxPngPixels or, with
// kGreyOnly, one that is not 8-bit grey.
Result<cv::Mat> DecodePng(std::string_view bytes, PngDecode mode);

// PNG bytes of a CV_8UC1 (grey) or CV_8UC3 (BGR, OpenCV's channel order) image; any row stride
// (a ROI of a larger Mat is fine). Favours speed over size (libpng's PNG_IMAGE_FLAG_FAST: no row
// filters, zlib level 3). InvalidArgument for an empty image, another type (named, e.g.
// "CV_16UC1") or more than kMaxPngPixels pixels; Internal if libpng fails.
Result<std::string> EncodePng(const cv::Mat& image);

// The same on files; errors are prefixed with the path. ReadPngFile returns NotFound for a
// missing file. WritePngFile writes atomically ("<path>.tmp" renamed into place).
Result<cv::Mat> ReadPngFile(const std::string& path, PngDecode mode);
Status WritePngFile(const std::string& path, const cv::Mat& image);

}  // namespace mav::dataset
