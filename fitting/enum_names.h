#pragma once

// One table of {value, name} pairs per enum, and the two look-ups every enum's ToString / FromString is
// written with: the spelling of a value and the value of a spelling. The names are what JSON outputs,
// manifests and the command line read and write, so each enum's table is its single source of truth.

#include <array>
#include <cstddef>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

namespace s2m {

template <typename Enum>
struct EnumName {
  Enum value;
  const char* name;
};

// The table's names in its order, comma-separated: what an error message lists as the accepted spellings.
template <typename Enum, std::size_t N>
std::string NamesOf(const std::array<EnumName<Enum>, N>& table) {
  std::string names;
  for (const EnumName<Enum>& entry : table) {
    if (!names.empty()) names += ", ";
    names += entry.name;
  }
  return names;
}

// The name of value; fallback when the table lacks it (a value cast from an out-of-range integer).
template <typename Enum, std::size_t N>
constexpr const char* NameOf(const std::array<EnumName<Enum>, N>& table, Enum value,
                             const char* fallback = "unknown") {
  for (const EnumName<Enum>& entry : table)
    if (entry.value == value) return entry.name;
  return fallback;
}

// The value spelt name, or nothing: for callers that report an unknown name in their own words.
template <typename Enum, std::size_t N>
constexpr std::optional<Enum> FindValue(const std::array<EnumName<Enum>, N>& table, std::string_view name) {
  for (const EnumName<Enum>& entry : table)
    if (name == entry.name) return entry.value;
  return std::nullopt;
}

// The value spelt name. Throws std::invalid_argument "unknown <what> '<name>' (<the accepted names>)".
template <typename Enum, std::size_t N>
Enum ValueOf(const std::array<EnumName<Enum>, N>& table, std::string_view name, std::string_view what) {
  if (const std::optional<Enum> value = FindValue(table, name)) return *value;
  throw std::invalid_argument("unknown " + std::string(what) + " '" + std::string(name) + "' (" +
                              NamesOf(table) + ")");
}

}  // namespace s2m
