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
  InputError(std::string file_name, int line_number, std::string key_name, std::string message)
      : std::runtime_error(format(file_name, line_number, key_name, message)),
        file(std::move(file_name)),
        line(line_number),
        key(std::move(key_name)) {}

  // Built with append: GCC 12 gives a false -Wrestrict warning on "literal" + std::string&&.
  static std::string format(const std::string& file, int line, const std::string& key,
                            const std::string& message) {
    std::string text = file;
    if (line > 0) text.append(":").append(std::to_string(line));
    text.append(": ");
    if (!key.empty()) text.append(key).append(": ");
    return text.append(message);
  }

  std::string file;
  int line;
  std::string key;
};

}  // namespace subslip
