// Test helpers for what subslip shows on a terminal: display columns of a line counted
// independently of the program's own counting, a pseudo-terminal of a chosen width to run the
// subslip binary on, and a minimal terminal screen that replays what was written there (to see
// whether a line wrapped or a progress bar left lines behind).
#pragma once

#include <fcntl.h>
#include <pty.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

namespace subslip::testing {

// Display columns of UTF-8 text: one per code point, two for the CJK block U+3000..U+9FFF
// (lead bytes 0xE3..0xE9), none for the combining accents U+0300..U+036F (0xCC 0x80..0xCD 0xAF):
// the wide and zero-width characters the tests use.
inline int columns_of(const std::string& line) {
  int columns = 0;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const auto c = static_cast<unsigned char>(line[i]);
    const auto next = i + 1 < line.size() ? static_cast<unsigned char>(line[i + 1]) : 0;
    if ((c & 0xC0) == 0x80 || c == 0xCC || (c == 0xCD && next <= 0xAF)) continue;
    columns += c >= 0xE3 && c <= 0xE9 ? 2 : 1;
  }
  return columns;
}

inline std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// A terminal `columns` wide replaying bytes: printable characters advance the cursor and wrap
// onto a new row when written past the last column (as xterm does), '\r' returns to the row's
// start, '\n' moves down, ESC [ K clears to the end of the row; other escape sequences are
// skipped.
struct Screen {
  int columns;
  std::size_t row = 0;
  int column = 0;
  int wraps = 0;  // automatic wraps: a line wider than the terminal

  explicit Screen(int width) : columns(width) {}

  void feed(const std::string& bytes) {
    for (std::size_t i = 0; i < bytes.size(); ++i) {
      const char c = bytes[i];
      if (c == '\r') {
        column = 0;
      } else if (c == '\n') {
        new_row();
      } else if (c == '\x1b') {
        i = escape(bytes, i);
      } else if ((static_cast<unsigned char>(c) & 0xC0) == 0x80) {
        if (column > 0) cell(column - 1) += c;  // continues the character before
      } else {
        if (column >= columns) {
          ++wraps;
          new_row();
        }
        cell(column++) = std::string(1, c);
      }
    }
  }

  std::vector<std::string> text_rows() const {
    std::vector<std::string> out;
    for (const auto& r : cells) {
      std::string line;
      for (const auto& ch : r) line += ch;
      line.erase(line.find_last_not_of(' ') + 1);
      out.push_back(line);
    }
    while (!out.empty() && out.back().empty()) out.pop_back();
    return out;
  }

 private:
  std::vector<std::vector<std::string>> cells{{}};  // per row, one character (UTF-8) a column

  void new_row() {
    ++row;
    column = 0;
    if (cells.size() <= row) cells.resize(row + 1);
  }

  std::string& cell(int k) {
    auto& r = cells[row];
    while (static_cast<int>(r.size()) <= k) r.emplace_back(" ");
    return r[static_cast<std::size_t>(k)];
  }

  // Returns the index of the sequence's last byte.
  std::size_t escape(const std::string& bytes, std::size_t at) {
    if (at + 1 >= bytes.size() || bytes[at + 1] != '[') return at;
    std::size_t end = at + 2;
    while (end < bytes.size() && !(bytes[end] >= '@' && bytes[end] <= '~')) ++end;
    if (end < bytes.size() && bytes[end] == 'K' && cells[row].size() > std::size_t(column))
      cells[row].resize(static_cast<std::size_t>(column));
    return end;
  }
};

struct TerminalRun {
  int code = -1;
  std::string terminal;  // every byte written on the terminal
};

// Runs `SUBSLIP_BINARY args...` in `dir` with stderr on a pseudo-terminal `columns` wide, and
// stdout on it too, or into `stdout_file` when one is given.
inline TerminalRun run_on_terminal(const std::filesystem::path& dir,
                                   const std::vector<std::string>& args, int columns,
                                   const std::filesystem::path& stdout_file = {}) {
  int master = -1;
  int slave = -1;
  winsize size{};
  size.ws_col = static_cast<unsigned short>(columns);
  size.ws_row = 50;
  if (::openpty(&master, &slave, nullptr, nullptr, &size) != 0) return {-1, "openpty failed"};
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(master);
    if (::chdir(dir.c_str()) != 0) ::_exit(127);
    const int out = stdout_file.empty()
                        ? slave
                        : ::open(stdout_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(out, 1);
    ::dup2(slave, 2);
    std::vector<std::string> all{SUBSLIP_BINARY};
    all.insert(all.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  ::close(slave);
  TerminalRun run;
  char buf[4096];
  for (;;) {  // until EIO: every end of the terminal's slave side is closed
    const ssize_t n = ::read(master, buf, sizeof buf);
    if (n > 0) {
      run.terminal.append(buf, static_cast<std::size_t>(n));
    } else if (!(n < 0 && errno == EINTR)) {
      break;
    }
  }
  ::close(master);
  int status = 0;
  if (::waitpid(pid, &status, 0) == pid && WIFEXITED(status)) run.code = WEXITSTATUS(status);
  return run;
}

}  // namespace subslip::testing
