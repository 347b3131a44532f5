// The precompiled header of vtsim_lib, the CLI and the tests (CMakeLists.txt, VTSIM_PCH): the
// headers nearly every translation unit parses, and the heaviest ones. Only third-party and standard
// headers: a vtsim header here would hide a missing include from the layering test's view and
// recompile everything on each edit.
#pragma once
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include <fmt/format.h>
#include <glm/glm.hpp>
#include <nlohmann/json.hpp>
