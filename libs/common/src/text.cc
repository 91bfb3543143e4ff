#include "mav/common/text.h"

#include <cmath>
#include <cstdint>
#include <cstdio>

namespace mav {
namespace {

// Length of the well-formed UTF-8 sequence starting at text[i] (RFC 3629: no overlong forms,
// no surrogates, nothing above U+10FFFF), or 0 if the byte there does not start one.
size_t Utf8SequenceLength(std::string_view text, size_t i) {
  const auto byte = [&](size_t k) { return static_cast<uint8_t>(text[k]); };
  const uint8_t lead = byte(i);
  size_t length = 0;
  uint8_t second_lo = 0x80, second_hi = 0xbf;
  if (lead >= 0xc2 && lead <= 0xdf) {
    length = 2;
  } else if (lead >= 0xe0 && lead <= 0xef) {
    length = 3;
    if (lead == 0xe0) second_lo = 0xa0;  // overlong below U+0800
    if (lead == 0xed) second_hi = 0x9f;  // UTF-16 surrogates
  } else if (lead >= 0xf0 && lead <= 0xf4) {
    length = 4;
    if (lead == 0xf0) second_lo = 0x90;  // overlong below U+10000
    if (lead == 0xf4) second_hi = 0x8f;  // above U+10FFFF
  } else {
    return 0;
  }
  if (i + length > text.size()) return 0;
  if (byte(i + 1) < second_lo || byte(i + 1) > second_hi) return 0;
  for (size_t k = 2; k < length; ++k) {
    if (byte(i + k) < 0x80 || byte(i + k) > 0xbf) return 0;
  }
  return length;
}

void AppendHex(std::string* out, uint8_t byte) {
  char buffer[8];
  std::snprintf(buffer, sizeof(buffer), "\\x%02x", byte);
  out->append(buffer);
}

}  // namespace

std::string QuoteForError(std::string_view value, size_t max_chars) {
  std::string out = "'";
  size_t i = 0;
  size_t kept = 0;
  while (i < value.size() && kept < max_chars) {
    const uint8_t c = static_cast<uint8_t>(value[i]);
    ++kept;
    if (c < 0x80) {
      switch (c) {
        case '\n':
          out += "\\n";
          break;
        case '\r':
          out += "\\r";
          break;
        case '\t':
          out += "\\t";
          break;
        case '\'':
          out += "\\'";
          break;
        case '\\':
          out += "\\\\";
          break;
        default:
          if (c < 0x20 || c == 0x7f) {
            AppendHex(&out, c);
          } else {
            out += static_cast<char>(c);
          }
      }
      ++i;
      continue;
    }
    const size_t length = Utf8SequenceLength(value, i);
    // U+0080..U+009F (C1 controls, encoded c2 80..c2 9f) are escaped like the C0 ones.
    const bool c1_control = length == 2 && c == 0xc2 && static_cast<uint8_t>(value[i + 1]) < 0xa0;
    if (length == 0 || c1_control) {
      const size_t n = length == 0 ? 1 : length;
      for (size_t k = 0; k < n; ++k) AppendHex(&out, static_cast<uint8_t>(value[i + k]));
      i += n;
    } else {
      out.append(value.substr(i, length));
      i += length;
    }
  }
  if (i < value.size()) {
    return out + "...' (" + std::to_string(value.size()) + " bytes)";
  }
  return out + "'";
}

std::string JsonQuote(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\u%04x", c);
      out += buf;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string JsonNumber(double v) {
  if (!std::isfinite(v)) return "null";  // JSON has no NaN/inf
  char buf[32];
  // Counts (voxels, box positions, points) exactly; other figures to 6 significant digits.
  const bool integral = std::fabs(v) < 1e15 && v == std::floor(v);
  std::snprintf(buf, sizeof(buf), integral ? "%.0f" : "%.6g", v);
  return buf;
}

}  // namespace mav
