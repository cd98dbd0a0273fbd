#pragma once
// Internal helpers for the text parts of the formats: lines with numbers and offsets, tokens, numbers.

#include <charconv>
#include <string>
#include <string_view>
#include <vector>

namespace s2m::formats {

struct Line {
  std::string_view text;   // without the line terminator (\n or \r\n)
  std::size_t number = 0;  // 1-based
  std::size_t offset = 0;  // byte offset of the line's first character
};

class LineReader {
 public:
  explicit LineReader(std::string_view bytes, std::size_t start = 0) : bytes_(bytes), pos_(start) {}
  bool Next(Line& line) {
    if (pos_ >= bytes_.size()) return false;
    const std::size_t end = bytes_.find('\n', pos_);
    const std::size_t stop = end == std::string_view::npos ? bytes_.size() : end;
    std::string_view text = bytes_.substr(pos_, stop - pos_);
    if (!text.empty() && text.back() == '\r') text.remove_suffix(1);
    line = {text, ++number_, pos_};
    pos_ = end == std::string_view::npos ? bytes_.size() : end + 1;
    return true;
  }
  std::size_t position() const { return pos_; }  // offset of the next line
  std::size_t line_number() const { return number_; }

 private:
  std::string_view bytes_;
  std::size_t pos_ = 0;
  std::size_t number_ = 0;
};

// Splits on whitespace, and also on ',' and ';' when `csv` is set.
inline void Tokenize(std::string_view text, std::vector<std::string_view>& tokens, bool csv = false) {
  tokens.clear();
  auto is_sep = [csv](char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f' || (csv && (c == ',' || c == ';'));
  };
  std::size_t i = 0;
  while (i < text.size()) {
    while (i < text.size() && is_sep(text[i])) ++i;
    std::size_t j = i;
    while (j < text.size() && !is_sep(text[j])) ++j;
    if (j > i) tokens.push_back(text.substr(i, j - i));
    i = j;
  }
}

// Locale-independent; accepts a leading '+'. Returns false unless the whole token is a number (nan/inf
// included: callers decide whether non-finite values are allowed).
inline bool ParseDouble(std::string_view token, double& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  return ec == std::errc() && ptr == token.data() + token.size();
}

template <class Int>
bool ParseInteger(std::string_view token, Int& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  return ec == std::errc() && ptr == token.data() + token.size();
}

inline std::string Quoted(std::string_view s) {
  constexpr std::size_t kMax = 40;
  std::string out = "'" + std::string(s.substr(0, kMax));
  if (s.size() > kMax) out += "...";
  return out + "'";
}

}  // namespace s2m::formats
