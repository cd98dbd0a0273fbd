#pragma once
// Internal: E57's bit-pack codec (ASTM E2807, the only codec the standard defines; docs/e57.md). Every field
// of a compressed vector's record has its own bytestream. Float fields store IEEE 754 binary32 or binary64
// values, little-endian. Integer and ScaledInteger fields store (value - minimum) in exactly
// ceil(log2(maximum - minimum
// + 1)) bits, packed least significant bit first into a bitstream that continues from one data packet to the
// next (a value may straddle two packets). A field whose minimum equals its maximum takes no bits at all.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace s2m::formats::e57 {

enum class FieldType { kFloat32, kFloat64, kInteger, kScaledInteger };
const char* ToString(FieldType type);

struct FieldCodec {
  FieldType type = FieldType::kFloat64;
  std::int64_t minimum = 0;  // Integer and ScaledInteger: the raw integer's range, inclusive
  std::int64_t maximum = 0;
  double scale = 1.0;  // ScaledInteger: value = raw * scale + offset
  double offset = 0.0;

  // Bits per value in the bytestream: 32, 64, or for integers ceil(log2(maximum - minimum + 1)) in 0..64.
  int BitWidth() const;
};

// The bits of one bytestream, fed packet by packet. Bits are consumed least significant first.
class BitReader {
 public:
  void Append(const unsigned char* data, std::size_t size);
  std::uint64_t bits_available() const { return 8 * static_cast<std::uint64_t>(bytes_.size()) - bit_; }
  // The next `bits` (0..64) bits as an unsigned number; the caller has checked bits_available().
  std::uint64_t Take(int bits);

 private:
  std::vector<unsigned char> bytes_;
  std::uint64_t bit_ = 0;  // position of the next unread bit in bytes_
};

// Writes values of `bits` (0..64) bits, least significant first, into a growing byte buffer.
class BitWriter {
 public:
  void Put(std::uint64_t value, int bits);
  std::uint64_t bit_count() const { return bits_; }
  // All bytes so far; the last one is padded with zero bits.
  const std::vector<unsigned char>& bytes() const { return bytes_; }

 private:
  std::vector<unsigned char> bytes_;
  std::uint64_t bits_ = 0;
};

// The bits of one value. Float fields: the IEEE bits of `value` (binary32 rounds it). Integer fields: the
// integer (for ScaledInteger the raw integer, before scaling) minus the minimum; the caller keeps it in
// range.
std::uint64_t EncodeFloat(const FieldCodec& codec, double value);
std::uint64_t EncodeInteger(const FieldCodec& codec, std::int64_t integer);
// The value of a field's bits: floats as stored, integers as minimum + bits, ScaledInteger scaled and offset.
// Returns false for an integer beyond the field's maximum (bits a valid stream cannot hold).
bool Decode(const FieldCodec& codec, std::uint64_t bits, double& value);

}  // namespace s2m::formats::e57
