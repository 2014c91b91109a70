// Text files as editors save them, turned into the UTF-8 every reader of subslip works on (and
// that a result file stores in /scene): UTF-8 with or without a byte-order mark, or UTF-16 /
// UTF-32 with one (Windows editors), converted with iconv. What is not text in one of those
// encodings (a binary file, UTF-16 without a mark, Latin-1 bytes) is refused with one short
// InputError naming the file, the line and the byte, rather than parsed into garbage or stored
// as invalid UTF-8 that readers (h5py) cannot decode.
#pragma once

#include <string>

namespace subslip::io {

// `bytes` as UTF-8 without a byte-order mark; throws InputError (naming `file_name`) when they
// are not UTF-8, UTF-16 or UTF-32 text.
std::string decode_text(std::string bytes, const std::string& file_name);

}  // namespace subslip::io
