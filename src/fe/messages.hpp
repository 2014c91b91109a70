// What the entry points say when they refuse a step: one line on stderr (at most kPrinted lines
// in a process, so that a bad deck does not flood the FE code's log from every integration
// point and every cutback), and the last message of each thread for subslip_fe_last_message.
#pragma once

#include <string>

namespace subslip::fe {

inline constexpr int kPrinted = 50;

void clear_message();
// Records `text` as this thread's last message and prints it as "subslip <entry>: <text>".
void refuse(const char* entry, const std::string& text);
const std::string& last_message();

}  // namespace subslip::fe
