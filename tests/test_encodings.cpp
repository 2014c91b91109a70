// Text encodings of the files subslip reads: a byte-order mark is accepted wherever
// text is read; UTF-16 and UTF-32 with a mark are converted to UTF-8 (what /scene stores);
// Latin-1 bytes, NUL bytes and other binary content are refused naming file, line and byte.
#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <string_view>

#include "subslip/io/input_error.hpp"
#include "subslip/io/orientation_file.hpp"
#include "subslip/io/text_encoding.hpp"
#include "subslip/io/yaml_checked.hpp"

using namespace subslip;
using namespace subslip::io;

namespace {

// `utf8` (ASCII and 2-byte characters only) as UTF-16 code units, little or big endian.
std::string utf16(std::string_view utf8, bool little_endian) {
  std::string out = little_endian ? "\xFF\xFE" : "\xFE\xFF";
  for (std::size_t i = 0; i < utf8.size(); ++i) {
    auto c = static_cast<unsigned char>(utf8[i]);
    unsigned unit = c;
    if (c >= 0xC0) unit = ((c & 0x1Fu) << 6) | (static_cast<unsigned char>(utf8[++i]) & 0x3Fu);
    const char lo = static_cast<char>(unit & 0xFF), hi = static_cast<char>(unit >> 8);
    out += little_endian ? std::string{lo, hi} : std::string{hi, lo};
  }
  return out;
}

std::string utf32le(std::string_view ascii) {
  std::string out("\xFF\xFE\0\0", 4);
  for (char c : ascii) out += std::string{c, '\0', '\0', '\0'};
  return out;
}

// The InputError of decoding `bytes` as "f.yaml".
InputError decode_error(const std::string& bytes) {
  try {
    decode_text(bytes, "f.yaml");
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "accepted";
  return InputError("", 0, "", "");
}

const std::string kText = "title: \"Fe\xC3\xA9 r\xC3\xA9sum\xC3\xA9\"\nn: 1\n";  // UTF-8 é

}  // namespace

TEST(Encoding, Utf8PassesAndItsByteOrderMarkIsDropped) {
  EXPECT_EQ(decode_text(kText, "f.yaml"), kText);
  EXPECT_EQ(decode_text("\xEF\xBB\xBF" + kText, "f.yaml"), kText);
}

TEST(Encoding, Utf16And32WithAMarkBecomeUtf8) {
  EXPECT_EQ(decode_text(utf16(kText, true), "f.yaml"), kText);
  EXPECT_EQ(decode_text(utf16(kText, false), "f.yaml"), kText);
  EXPECT_EQ(decode_text(utf32le("a: 1\n"), "f.yaml"), "a: 1\n");
}

TEST(Encoding, Latin1IsRefusedNamingLineAndByte) {
  const InputError e = decode_error("a: 1\ntitle: caf\xE9\n");
  EXPECT_EQ(e.file, "f.yaml");
  EXPECT_EQ(e.line, 2);
  EXPECT_NE(e.message.find("byte 0xE9 at column 11 is not UTF-8"), std::string::npos) << e.what();
}

TEST(Encoding, NulBytesAreRefusedAsNotText) {
  const InputError e = decode_error(std::string("a: 1\nb\0c\n", 9));
  EXPECT_EQ(e.line, 2);
  EXPECT_NE(e.message.find("not a text file"), std::string::npos) << e.what();
  // UTF-16 without a mark is full of NULs: the same message, which names that case.
  const std::string unmarked = utf16("a: 1\n", true).substr(2);
  EXPECT_NE(decode_error(unmarked).message.find("UTF-16 without a byte-order mark"),
            std::string::npos);
}

TEST(Encoding, BrokenUtf16IsRefused) {
  const std::string odd = utf16("a: 1\n", true) + "x";  // an odd byte count
  EXPECT_NE(decode_error(odd).message.find("not valid UTF-16LE"), std::string::npos);
}

// A UTF-16 scene is parsed, and its text() (what /scene stores) is UTF-8.
TEST(Encoding, Utf16SceneParsesAndKeepsUtf8Text) {
  const YamlDocument d = YamlDocument::from_string(utf16(kText, true), "f.yaml");
  EXPECT_EQ(d.text(), kText);
  EXPECT_EQ(d.root().get_string("title"), "Fe\xC3\xA9 r\xC3\xA9sum\xC3\xA9");
  EXPECT_EQ(d.root().get_int("n"), 1);
}

TEST(Encoding, OrientationFilesAcceptAByteOrderMark) {
  const std::string text =
      "# subslip-orientations convention=bunge-euler-deg\n10 20 30\n40 50 60\n";
  for (const std::string& bytes : {"\xEF\xBB\xBF" + text, utf16(text, true), utf16(text, false)}) {
    std::istringstream in(bytes);
    const auto grains = read_orientations(in, "o.txt");
    ASSERT_EQ(grains.size(), 2u);
    std::istringstream plain(text);
    const auto expected = read_orientations(plain, "o.txt");
    EXPECT_EQ(grains[1].q.w, expected[1].q.w);
    EXPECT_EQ(grains[1].q.z, expected[1].q.z);
  }
}

// yaml-cpp's limit on nesting says "bad file"; the message says what is wrong.
TEST(Encoding, DeeplyNestedYamlIsNamedAsSuch) {
  std::string text = "a: ";
  text.append(5000, '[').append(5000, ']').append("\n");
  try {
    YamlDocument::from_string(text, "deep.yaml");
    FAIL() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line, 1);
    EXPECT_NE(e.message.find("YAML nested too deeply: hundreds of mappings or sequences"),
              std::string::npos)
        << e.what();
  }
}
