#pragma once
// The memory this process may use: what allocations that must fit (the real clock's VRAM arena and
// its reserved RAM-cache buffers) are checked against before they are made. Under overcommit such
// an allocation succeeds and the first writes bring in the OOM killer, so the check is the only
// clean refusal. The limit is the machine's physical memory or, when lower, the memory limit of the
// process's cgroup or any of its ancestors (a container, a CI runner, a systemd slice): there the
// OOM killer acts at the cgroup's limit, whatever the machine has.
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>

namespace vtsim {

// sysconf(_SC_PHYS_PAGES) · page size; UINT64_MAX when the system does not say.
std::uint64_t physical_memory_bytes();

// Reads a file whole; nullopt when it cannot be read (absent, no permission).
using ReadTextFile = std::function<std::optional<std::string>(const std::string& path)>;

// The least memory limit on the cgroup `self_cgroup` names (the text of /proc/self/cgroup) and its
// ancestors, found through the cgroup mounts of `mountinfo` (the text of /proc/self/mountinfo):
// cgroup v2 `memory.max` ("max": none), cgroup v1 `memory.limit_in_bytes` of the memory
// controller's hierarchy, through the mount whose directory holds the cgroup. UINT64_MAX when there
// is none, no mount holds the cgroup, or nothing can be read or parsed: the
// limit only ever lowers the physical one, so an unreadable cgroup tree falls back to that.
std::uint64_t cgroup_memory_limit(std::string_view self_cgroup, std::string_view mountinfo, const ReadTextFile& read);

// min(physical_memory_bytes(), the cgroup limit of this process read from /proc and /sys).
std::uint64_t usable_memory_bytes();

}  // namespace vtsim
