// The one error type for bad input files (scene files, orientation files, ...).
//
// Every problem found while reading a file is reported as "FILE:LINE: KEY: MESSAGE" so that an
// editor or a terminal can jump to it. LINE is 1-based; line 0 means the problem has no line
// (missing file, empty file) and is printed as "FILE: KEY: MESSAGE". KEY names what is wrong (a
// YAML key, a column name, "header", ...); an empty key is left out: "FILE:LINE: MESSAGE".
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

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

 protected:
  // An error whose what() is `text` (InputErrors: every error, one per line).
  InputError(const InputError& first, const std::string& text)
      : std::runtime_error(text),
        file(first.file),
        line(first.line),
        key(first.key),
        message(first.message) {}
};

// Several problems of one input, found in one reading and reported together. It is the first of
// them as an InputError (its file, line, key and message), so that code and tests that look at
// one error see the first; what() lists them all, one "FILE:LINE: KEY: MESSAGE" per line, and a
// last line when the reading stopped at the limit.
struct InputErrors : InputError {
  InputErrors(std::vector<InputError> errors, bool stopped_at_limit)
      : InputError(errors.at(0), text_of(errors, stopped_at_limit)),
        all(std::move(errors)),
        stopped(stopped_at_limit) {}

  // The line that ends a list cut at the limit.
  static std::string limit_line(std::size_t count) {
    return "(stopped after " + std::to_string(count) +
           " errors; correct these and run again to see any others)";
  }

  std::vector<InputError> all;  // in the order found, the first one included
  bool stopped;                 // the reading stopped at the limit: there may be more

 private:
  static std::string text_of(const std::vector<InputError>& errors, bool stopped_at_limit) {
    std::string text;
    for (const InputError& e : errors) text.append(text.empty() ? "" : "\n").append(e.what());
    if (stopped_at_limit) text.append("\n").append(limit_line(errors.size()));
    return text;
  }
};

// The errors of one reading of an input, so that one run reports every problem (up to
// `limit`) rather than one per attempt. A part that fails is skipped with what depends on it:
// an error that only follows from an earlier one is not reported.
class InputErrorList {
 public:
  static constexpr std::size_t kDefaultLimit = 20;

  explicit InputErrorList(std::size_t limit = kDefaultLimit) : limit_(limit) {}

  // Runs `part`; an InputError it throws (one or several) is recorded and false returned. At
  // the limit, the errors so far are thrown at once.
  template <class Part>
  bool attempt(Part&& part) {
    try {
      std::forward<Part>(part)();
      return true;
    } catch (const InputErrors& e) {
      for (const InputError& one : e.all) add(one);
      if (e.stopped) throw_all(true);
    } catch (const InputError& e) {
      add(e);
    }
    return false;
  }

  // Records `e` (an error equal to one recorded is not repeated, nor a missing key beside an
  // unknown one); throws at the limit.
  void add(const InputError& e) {
    for (const InputError& known : errors_) {
      if (same(known, e) || follows(e, known)) return;
    }
    std::erase_if(errors_, [&](const InputError& known) { return follows(known, e); });
    errors_.push_back(e);
    if (errors_.size() >= limit_) throw_all(true);
  }

  bool empty() const { return errors_.empty(); }
  std::size_t size() const { return errors_.size(); }
  const std::vector<InputError>& errors() const { return errors_; }

  // Nothing when no error was recorded; else the one error, or InputErrors with all of them.
  void throw_if_any() const {
    if (errors_.size() == 1) throw errors_.front();
    if (!errors_.empty()) throw_all(false);
  }

  static bool same(const InputError& a, const InputError& b) {
    return a.file == b.file && a.line == b.line && a.key == b.key && a.message == b.message;
  }

  // Whether `later` only follows from `unknown`: a key missing from a mapping that has an
  // unknown key (most likely the missing one misspelt: "eta" for "eta_v").
  static bool follows(const InputError& later, const InputError& unknown) {
    return later.message == kMissingKey && unknown.message.starts_with(kUnknownKey) &&
           later.file == unknown.file && parent(later.key) == parent(unknown.key);
  }

  // The messages `follows` knows (yaml_checked.hpp writes them).
  static constexpr std::string_view kMissingKey = "missing required key";
  static constexpr std::string_view kUnknownKey = "unknown key ";

 private:
  [[noreturn]] void throw_all(bool stopped) const { throw InputErrors(errors_, stopped); }

  // The key path of the mapping that holds `key`: "law.overstress" for "law.overstress.eta",
  // "loading[0]" for "loading[0].slide", "" for a top-level key.
  static std::string_view parent(std::string_view key) {
    const std::size_t dot = key.rfind('.');
    return dot == std::string_view::npos ? std::string_view() : key.substr(0, dot);
  }

  std::size_t limit_;
  std::vector<InputError> errors_;
};

}  // namespace subslip
