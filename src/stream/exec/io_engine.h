#pragma once
// The IO pool's read engines (config io.engine; stream/exec/io_pool.h, docs/real-engine.md §1).
// Adding one is a line in io_engines() (io_pool.cpp) and a worker loop in io_pool.cpp.
#include <cstdint>
#include <string_view>

#include "core/registry.h"

namespace vtsim {

enum class IoEngine : std::uint8_t { psync, io_uring };
struct IoEngineInfo {
  std::string_view name;
  std::string_view why;
  IoEngine engine;
};
const Registry<IoEngineInfo>& io_engines();
std::string_view engine_name(IoEngine e);

}  // namespace vtsim
