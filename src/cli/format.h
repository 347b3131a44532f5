#pragma once
// Byte counts for people, one formatter for every command: binary units with two decimals
// ("1.50 KiB", "2.00 GiB", up to PiB), whole bytes below 1 KiB ("512 B").
#include <fmt/format.h>

#include <string>

namespace vtsim::cli {

inline std::string human_bytes(double b) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB", "PiB"};
  int u = 0;
  while (b >= 1024.0 && u < 5) b /= 1024.0, ++u;
  return fmt::format("{:.{}f} {}", b, u == 0 ? 0 : 2, units[u]);
}

}  // namespace vtsim::cli
