#pragma once
// Text helpers for messages that quote what a user or a file gave us.
//
// An error message must name the offending value, but must not echo it whole: a value of several
// kilobytes turns an InvalidArgument into a RESOURCE_EXHAUSTED once a service puts the message into
// gRPC's status metadata (8 KiB by default), and control characters or broken UTF-8 make logs and
// terminals unreadable (and a proto3 `string` field refuses invalid UTF-8).

#include <cstddef>
#include <string>
#include <string_view>

namespace mav {

// The value in single quotes, safe to embed in any error message:
//  * at most `max_chars` characters of the value are kept; a longer value ends with
//    "...' (N bytes)", N being the whole value's size in bytes;
//  * control characters (and DEL) become \n, \r, \t or \xNN; a quote or backslash is escaped
//    (\' and \\), so the quoted text cannot end early;
//  * valid UTF-8 sequences are kept as they are (a character is never cut in half); every byte
//    that is not part of one becomes \xNN, so the result is always valid UTF-8.
// The result therefore has at most about 4 * max_chars + 30 bytes.
// Examples: QuoteForError("abc") == "'abc'"; QuoteForError("a\nb") == "'a\\nb'";
//           QuoteForError(std::string(10000, 'x'), 3) == "'xxx...' (10000 bytes)".
std::string QuoteForError(std::string_view value, size_t max_chars = 64);

// A JSON string literal (quotes, backslashes and control characters escaped).
std::string JsonQuote(const std::string& s);
// A JSON number: integers exactly, others to 6 significant digits; null for NaN or infinity.
std::string JsonNumber(double v);

}  // namespace mav
