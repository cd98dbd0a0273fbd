#pragma once
// Internal: typed scalar reads from a byte buffer with explicit endianness.

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>

namespace s2m::formats {

enum class ScalarType {
  kInt8,
  kUint8,
  kInt16,
  kUint16,
  kInt32,
  kUint32,
  kInt64,
  kUint64,
  kFloat32,
  kFloat64
};

inline std::size_t SizeOf(ScalarType t) {
  switch (t) {
    case ScalarType::kInt8:
    case ScalarType::kUint8:
      return 1;
    case ScalarType::kInt16:
    case ScalarType::kUint16:
      return 2;
    case ScalarType::kInt32:
    case ScalarType::kUint32:
    case ScalarType::kFloat32:
      return 4;
    case ScalarType::kInt64:
    case ScalarType::kUint64:
    case ScalarType::kFloat64:
      return 8;
  }
  return 0;
}

template <class T>
T LoadScalar(const char* p, bool little_endian) {
  unsigned char raw[sizeof(T)];
  std::memcpy(raw, p, sizeof(T));
  if (little_endian != (std::endian::native == std::endian::little)) {
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(raw[i], raw[sizeof(T) - 1 - i]);
  }
  T value;
  std::memcpy(&value, raw, sizeof(T));
  return value;
}

// Reads one scalar of type t at p (the caller has checked that SizeOf(t) bytes are available).
inline double LoadAsDouble(const char* p, ScalarType t, bool little_endian) {
  switch (t) {
    case ScalarType::kInt8:
      return LoadScalar<std::int8_t>(p, little_endian);
    case ScalarType::kUint8:
      return LoadScalar<std::uint8_t>(p, little_endian);
    case ScalarType::kInt16:
      return LoadScalar<std::int16_t>(p, little_endian);
    case ScalarType::kUint16:
      return LoadScalar<std::uint16_t>(p, little_endian);
    case ScalarType::kInt32:
      return LoadScalar<std::int32_t>(p, little_endian);
    case ScalarType::kUint32:
      return LoadScalar<std::uint32_t>(p, little_endian);
    case ScalarType::kInt64:
      return static_cast<double>(LoadScalar<std::int64_t>(p, little_endian));
    case ScalarType::kUint64:
      return static_cast<double>(LoadScalar<std::uint64_t>(p, little_endian));
    case ScalarType::kFloat32:
      return LoadScalar<float>(p, little_endian);
    case ScalarType::kFloat64:
      return LoadScalar<double>(p, little_endian);
  }
  return 0.0;
}

// True when v is a whole number std::int64_t holds (-2^63 <= v < 2^63). Converting any other double (NaN,
// an infinity, a fraction's truncation aside, or a value out of range) to an integer type is undefined
// behaviour, so every label or index a file states as a number is checked with this first.
inline bool IsWholeInt64(double v) {
  return v == std::floor(v) && v >= -9223372036854775808.0 && v < 9223372036854775808.0;
}

}  // namespace s2m::formats
