// The one error type for bad input files (scene files, orientation files, ...).
//
// Every problem found while reading a file is reported as "FILE:LINE: KEY: MESSAGE" so that an
// editor or a terminal can jump to it. LINE is 1-based; line 0 means the problem has no line
// (missing file, empty file) and is printed as "FILE: KEY: MESSAGE". KEY names what is wrong (a
// YAML key, a column name, "header", ...); an empty key is left out: "FILE:LINE: MESSAGE".
#pragma once

#include <stdexcept>
#include <string>
#include <utility>

namespace subslip {

struct InputError : std::runtime_error {
  InputError(std::string file_name, int line_number, std::string key_name, std::string text)
      : std::runtime_error(format(file_name, line_number, key_name, text)),
        file(std::move(file_name)),
        line(line_number),
        key(std::move(key_name)),
        message(std::move(text)) {}

  // Built with append: GCC 12 gives a false -Wrestrict warning on "literal" + std::string&&.
  static std::string format(const std::string& file, int line, const std::string& key,
                            const std::string& message) {
    std::string text = printable(file);
    if (line > 0) text.append(":").append(std::to_string(line));
    text.append(": ");
    if (!key.empty()) text.append(printable(key)).append(": ");
    return text.append(printable(message));
  }

  // Control bytes as \xNN (newlines and tabs kept): a NUL from a broken file would end what()
  // early, and others would garble the terminal.
  static std::string printable(const std::string& s) {
    static constexpr char kHex[] = "0123456789abcdef";
    std::string out;
    out.reserve(s.size());
    for (const char c : s) {
      const auto b = static_cast<unsigned char>(c);
      if ((b < 0x20 && c != '\n' && c != '\t') || b == 0x7f) {
        out.append("\\x").push_back(kHex[b >> 4]);
        out.push_back(kHex[b & 0xf]);
      } else {
        out.push_back(c);
      }
    }
    return out;
  }

  std::string file;
  int line;
  std::string key;
  std::string message;  // without the "FILE:LINE: KEY: " prefix
};

}  // namespace subslip
