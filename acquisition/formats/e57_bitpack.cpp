#include "acquisition/formats/e57_bitpack.h"

#include <bit>
#include <cmath>
#include <cstring>

namespace s2m::formats::e57 {

const char* ToString(FieldType type) {
  switch (type) {
    case FieldType::kFloat32:
      return "Float (single)";
    case FieldType::kFloat64:
      return "Float (double)";
    case FieldType::kInteger:
      return "Integer";
    case FieldType::kScaledInteger:
      return "ScaledInteger";
  }
  return "?";
}

int FieldCodec::BitWidth() const {
  switch (type) {
    case FieldType::kFloat32:
      return 32;
    case FieldType::kFloat64:
      return 64;
    case FieldType::kInteger:
    case FieldType::kScaledInteger: {
      // maximum - minimum in unsigned arithmetic: exact for every pair with minimum <= maximum.
      const std::uint64_t range = static_cast<std::uint64_t>(maximum) - static_cast<std::uint64_t>(minimum);
      return range == 0 ? 0 : 64 - std::countl_zero(range);
    }
  }
  return 0;
}

void BitReader::Append(const unsigned char* data, std::size_t size) {
  const std::size_t consumed = static_cast<std::size_t>(bit_ / 8);
  if (consumed > 0) {
    bytes_.erase(bytes_.begin(), bytes_.begin() + static_cast<std::ptrdiff_t>(consumed));
    bit_ -= 8 * static_cast<std::uint64_t>(consumed);
  }
  bytes_.insert(bytes_.end(), data, data + size);
}

std::uint64_t BitReader::Take(int bits) {
  std::uint64_t value = 0;
  int got = 0;
  while (got < bits) {
    const unsigned byte = bytes_[static_cast<std::size_t>(bit_ / 8)];
    const int skip = static_cast<int>(bit_ % 8);
    const int n = std::min(8 - skip, bits - got);
    const std::uint64_t chunk = (byte >> skip) & ((1u << n) - 1u);
    value |= chunk << got;
    got += n;
    bit_ += static_cast<std::uint64_t>(n);
  }
  return value;
}

void BitWriter::Put(std::uint64_t value, int bits) {
  int done = 0;
  while (done < bits) {
    const int used = static_cast<int>(bits_ % 8);
    if (used == 0) bytes_.push_back(0);
    const int n = std::min(8 - used, bits - done);
    const unsigned chunk = static_cast<unsigned>((value >> done) & ((1u << n) - 1u));
    bytes_.back() = static_cast<unsigned char>(bytes_.back() | (chunk << used));
    done += n;
    bits_ += static_cast<std::uint64_t>(n);
  }
}

std::uint64_t EncodeFloat(const FieldCodec& codec, double value) {
  if (codec.type == FieldType::kFloat32) return std::bit_cast<std::uint32_t>(static_cast<float>(value));
  return std::bit_cast<std::uint64_t>(value);
}

std::uint64_t EncodeInteger(const FieldCodec& codec, std::int64_t integer) {
  return static_cast<std::uint64_t>(integer) - static_cast<std::uint64_t>(codec.minimum);
}

bool Decode(const FieldCodec& codec, std::uint64_t bits, double& value) {
  switch (codec.type) {
    case FieldType::kFloat32:
      value = std::bit_cast<float>(static_cast<std::uint32_t>(bits));
      return true;
    case FieldType::kFloat64:
      value = std::bit_cast<double>(bits);
      return true;
    case FieldType::kInteger:
    case FieldType::kScaledInteger: {
      const std::uint64_t range =
          static_cast<std::uint64_t>(codec.maximum) - static_cast<std::uint64_t>(codec.minimum);
      if (bits > range) return false;
      const auto integer = static_cast<std::int64_t>(static_cast<std::uint64_t>(codec.minimum) + bits);
      value = static_cast<double>(integer);
      if (codec.type == FieldType::kScaledInteger) value = value * codec.scale + codec.offset;
      return true;
    }
  }
  return false;
}

}  // namespace s2m::formats::e57
