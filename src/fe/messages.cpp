#include "messages.hpp"

#include <atomic>
#include <cstdio>
#include <cstring>

#include "subslip/fe/abaqus.h"

namespace subslip::fe {

namespace {
thread_local std::string last;
std::atomic<int> printed{0};
}  // namespace

void clear_message() {
  last.clear();
}

void refuse(const char* entry, const std::string& text) {
  last = text;
  const int k = printed.fetch_add(1);
  if (k < kPrinted)
    std::fprintf(stderr, "subslip %s: %s\n", entry, text.c_str());
  else if (k == kPrinted)
    std::fprintf(stderr, "subslip %s: further messages are not printed\n", entry);
}

const std::string& last_message() {
  return last;
}

}  // namespace subslip::fe

extern "C" __attribute__((visibility("default"))) int subslip_fe_last_message(char* buffer,
                                                                              int size) {
  const std::string& m = subslip::fe::last_message();
  if (buffer && size > 0) {
    const std::size_t n = std::min(m.size(), static_cast<std::size_t>(size - 1));
    std::memcpy(buffer, m.data(), n);
    buffer[n] = '\0';
  }
  return static_cast<int>(m.size());
}
