#pragma once
// Device strings of the virtual devices, "<scene>[,key=value...]" (devices/virtual_scanner.h
// ParseVirtualDevice, devices/virtual_horus.h ParseVirtualHorus): one splitter and one reading of numbers, so
// that both name a bad option the same way.

#include <cmath>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace s2m {

struct DeviceOptionList {
  std::string scene;                                         // the first item
  std::vector<std::pair<std::string, std::string>> options;  // (key, value) in the order given; keys distinct
};

// Splits `body` at commas and trims blanks around items, keys and values. Throws std::invalid_argument with
// `no_scene_message` when the first item is empty, and naming the item or key for an item that is not
// key=value or a key given twice.
inline DeviceOptionList SplitDeviceOptions(const std::string& body, const std::string& no_scene_message) {
  auto trim = [](const std::string& s) {
    const auto b = s.find_first_not_of(" \t\r\n"), e = s.find_last_not_of(" \t\r\n");
    return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
  };
  std::vector<std::string> items;
  std::stringstream in(body);
  for (std::string item; std::getline(in, item, ',');) items.push_back(trim(item));
  if (items.empty() || items.front().empty()) throw std::invalid_argument(no_scene_message);
  DeviceOptionList list;
  list.scene = items.front();
  std::set<std::string> seen;
  for (std::size_t i = 1; i < items.size(); ++i) {
    const std::size_t eq = items[i].find('=');
    if (eq == std::string::npos)
      throw std::invalid_argument("device option '" + items[i] + "' is not key=value");
    std::string key = trim(items[i].substr(0, eq)), value = trim(items[i].substr(eq + 1));
    if (!seen.insert(key).second) throw std::invalid_argument("device option '" + key + "' given twice");
    list.options.emplace_back(std::move(key), std::move(value));
  }
  return list;
}

// The option's value as a finite number; throws std::invalid_argument naming the key and the value.
inline double DeviceOptionNumber(const std::string& key, const std::string& value) {
  std::size_t used = 0;
  double x = 0;
  try {
    x = std::stod(value, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != value.size() || value.empty() || !std::isfinite(x))
    throw std::invalid_argument("device option '" + key + "': '" + value + "' is not a number");
  return x;
}

// The option's value as an integer in [minimum, maximum] (minimum 0 or 1: the message says non-negative or
// positive).
inline int DeviceOptionInteger(const std::string& key, const std::string& value, int minimum, int maximum) {
  const double x = DeviceOptionNumber(key, value);
  if (x != std::floor(x) || x < minimum || x > maximum)
    throw std::invalid_argument("device option '" + key + "': '" + value + "' is not a " +
                                (minimum >= 1 ? "positive" : "non-negative") + " integer");
  return static_cast<int>(x);
}

}  // namespace s2m
