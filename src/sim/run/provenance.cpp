#include "sim/run/provenance.h"

#include <fmt/format.h>
#include <sys/utsname.h>
#include <unistd.h>

#include <charconv>
#include <cstdint>
#include <fstream>
#include <thread>

#include "core/build_info.h"
#include "core/text.h"

namespace vtsim {

nlohmann::json build_json() {
  nlohmann::json b = {{"vtsim_version", build_version()}, {"vtsim_commit", build_commit()}};
#if defined(__clang__)
  b["compiler"] = std::string("clang ") + __clang_version__;
#elif defined(__GNUC__)
  b["compiler"] = std::string("gcc ") + __VERSION__;
#else
  b["compiler"] = "unknown";
#endif
#if defined(__OPTIMIZE__)
  b["optimized"] = true;
#else
  b["optimized"] = false;
#endif
  return b;
}

namespace {

// The value after ':' of the first line of `path` that starts with `key`; empty when none.
std::string provenance_proc_field(const char* path, const std::string& key) {
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(key, 0) != 0) continue;
    const auto colon = line.find(':');
    if (colon == std::string::npos) return {};
    const auto first = line.find_first_not_of(" \t", colon + 1);
    return first == std::string::npos ? std::string() : line.substr(first);
  }
  return {};
}

}  // namespace

nlohmann::json machine_json() {
  nlohmann::json m;
  char host[256] = {};
  m["hostname"] = gethostname(host, sizeof host - 1) == 0 && host[0] ? std::string(host) : std::string("unknown");
  const std::string cpu = provenance_proc_field("/proc/cpuinfo", "model name");
  m["cpu"] = cpu.empty() ? std::string("unknown") : cpu;
  m["logical_cores"] = std::thread::hardware_concurrency();
  // MemTotal is in kB (proc(5)).
  const std::string mem = provenance_proc_field("/proc/meminfo", "MemTotal");
  std::uint64_t kb = 0;
  std::from_chars(mem.data(), mem.data() + mem.size(), kb);
  m["memory_GiB"] = static_cast<double>(kb) / (1024.0 * 1024.0);
  utsname u{};
  m["os"] = uname(&u) == 0 ? std::string(u.sysname) + " " + u.release + " " + u.machine : std::string("unknown");
  return m;
}

namespace {

// A value in the config table's TOML syntax (ConfigField::get) as JSON of the field's type.
nlohmann::json provenance_config_value(ConfigType type, const std::string& v) {
  switch (type) {
    case ConfigType::boolean: return v == "true";
    case ConfigType::integer: {
      std::int64_t i = 0;
      if (text::parse_whole(v, i)) return i;
      break;
    }
    case ConfigType::real: {
      double d = 0;
      if (text::parse_whole(v, d)) return d;
      break;
    }
    case ConfigType::text:
      if (v.size() >= 2 && v.front() == '"' && v.back() == '"') return v.substr(1, v.size() - 2);
      break;
  }
  return v;  // a getter of its own syntax: as written
}

}  // namespace

nlohmann::json config_json(const ReplayConfig& cfg) {
  nlohmann::json c = nlohmann::json::object();
  for (const auto& f : replay_config_table().fields()) c[f.key] = provenance_config_value(f.type, f.get(cfg));
  return c;
}

nlohmann::json trace_hash_json(const Trace& trace) {
  if (trace.source_hash == 0) return nullptr;
  return fmt::format("fnv1a64:{:016x}", trace.source_hash);
}

}  // namespace vtsim
