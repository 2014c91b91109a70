#include "subslip/io/text_encoding.hpp"

#include <iconv.h>

#include <cerrno>
#include <cstdio>
#include <string_view>

#include "subslip/io/input_error.hpp"

namespace subslip::io {

namespace {

struct Encoding {
  std::string_view bom;
  const char* name;  // for iconv (the byte order is in the name: the mark is not passed on)
};

// Longest marks first: UTF-32LE's starts with UTF-16LE's.
constexpr Encoding kMarked[] = {{"\xEF\xBB\xBF", "UTF-8"},
                                {std::string_view("\xFF\xFE\0\0", 4), "UTF-32LE"},
                                {std::string_view("\0\0\xFE\xFF", 4), "UTF-32BE"},
                                {"\xFF\xFE", "UTF-16LE"},
                                {"\xFE\xFF", "UTF-16BE"}};

// The 1-based line of byte `offset` of `text`, and its column (bytes from the line's start).
struct Position {
  int line = 1;
  std::size_t column = 1;
};
Position position(std::string_view text, std::size_t offset) {
  Position p;
  for (std::size_t i = 0; i < offset && i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++p.line;
      p.column = 1;
    } else {
      ++p.column;
    }
  }
  return p;
}

std::string hex(unsigned char b) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "0x%02X", b);
  return buf;
}

// Converts `in` from `from` to UTF-8 with iconv; on a sequence that is not valid there, the
// offset of its first byte in `bad` and an empty result.
std::string to_utf8(std::string_view in, const char* from, std::size_t& bad) {
  bad = std::string::npos;
  iconv_t cd = ::iconv_open("UTF-8", from);
  if (cd == reinterpret_cast<iconv_t>(-1)) return {};
  std::string out(in.size() * 2 + 16, '\0');
  char* src = const_cast<char*>(in.data());
  std::size_t src_left = in.size();
  std::size_t done = 0;
  while (src_left > 0) {
    char* dst = out.data() + done;
    std::size_t dst_left = out.size() - done;
    const std::size_t r = ::iconv(cd, &src, &src_left, &dst, &dst_left);
    done = out.size() - dst_left;
    if (r != static_cast<std::size_t>(-1)) break;
    if (errno == E2BIG) {
      out.resize(out.size() * 2);
      continue;
    }
    bad = in.size() - src_left;  // EILSEQ, or EINVAL: cut off at the end
    break;
  }
  ::iconv_close(cd);
  out.resize(bad == std::string::npos ? done : 0);
  return out;
}

[[noreturn]] void refuse(const std::string& file, int line, const std::string& message) {
  throw InputError(file, line, "", message);
}

}  // namespace

std::string decode_text(std::string bytes, const std::string& file_name) {
  for (const Encoding& e : kMarked) {
    if (!std::string_view(bytes).starts_with(e.bom)) continue;
    const std::string_view body = std::string_view(bytes).substr(e.bom.size());
    std::size_t bad = 0;
    std::string text = to_utf8(body, e.name, bad);
    if (bad != std::string::npos) {
      refuse(file_name, 0,
             std::string("starts with a ") + e.name + " byte-order mark but is not valid " +
                 e.name + " (byte " + std::to_string(bad + e.bom.size()) + ")");
    }
    bytes = std::move(text);
    break;
  }
  // Without a mark the text must be UTF-8 (ASCII included) without NULs; the first problem in
  // the file is the one reported.
  std::size_t bad = 0;
  to_utf8(bytes, "UTF-8", bad);
  const std::size_t nul = bytes.find('\0');
  if (nul != std::string::npos && nul <= bad) {
    const Position at = position(bytes, nul);
    refuse(file_name, at.line,
           "a NUL byte at column " + std::to_string(at.column) +
               ": not a text file (a binary file, or UTF-16 without a byte-order mark?); save "
               "it as UTF-8");
  }
  if (bad != std::string::npos) {
    const Position at = position(bytes, bad);
    refuse(file_name, at.line,
           "byte " + hex(static_cast<unsigned char>(bytes[bad])) + " at column " +
               std::to_string(at.column) +
               " is not UTF-8 (Latin-1 or Windows-1252 text, or not text at all?); save the "
               "file as UTF-8");
  }
  return bytes;
}

}  // namespace subslip::io
