#include "core/host_memory.h"

#include <doctest/doctest.h>

#include <map>

using namespace vtsim;

namespace {

// A cgroup tree as a map from file path to contents.
ReadTextFile files(std::map<std::string, std::string> m) {
  return [m = std::move(m)](const std::string& path) -> std::optional<std::string> {
    const auto it = m.find(path);
    if (it == m.end()) return std::nullopt;
    return it->second;
  };
}

// /proc/self/mountinfo lines as Linux writes them (optional fields, then " - fstype source super").
const char* kMountsV2 = "22 1 0:21 / / rw,relatime - ext4 /dev/vda1 rw\n"
                        "30 22 0:26 / /sys/fs/cgroup rw,nosuid shared:4 - cgroup2 cgroup2 rw,nsdelegate\n";
const char* kMountsV1 = "22 1 0:21 / / rw,relatime - ext4 /dev/vda1 rw\n"
                        "31 30 0:28 / /sys/fs/cgroup/cpu rw,relatime - cgroup cgroup rw,cpu\n"
                        "34 30 0:31 / /sys/fs/cgroup/memory rw,relatime - cgroup cgroup rw,memory\n";

}  // namespace

TEST_CASE("host memory: cgroup v2 — the least memory.max from the process's cgroup up to the root") {
  const std::string self = "0::/ci/job\n";
  CHECK(cgroup_memory_limit(self, kMountsV2,
                            files({{"/sys/fs/cgroup/ci/job/memory.max", "max\n"},
                                   {"/sys/fs/cgroup/ci/memory.max", "8589934592\n"}})) == 8589934592u);
  CHECK(cgroup_memory_limit(self, kMountsV2,
                            files({{"/sys/fs/cgroup/ci/job/memory.max", "1073741824\n"},
                                   {"/sys/fs/cgroup/ci/memory.max", "8589934592\n"}})) == 1073741824u);
  // "max" everywhere, or no files (the root has no memory.max): no limit.
  CHECK(cgroup_memory_limit(self, kMountsV2, files({{"/sys/fs/cgroup/ci/job/memory.max", "max\n"}})) == UINT64_MAX);
  CHECK(cgroup_memory_limit(self, kMountsV2, files({})) == UINT64_MAX);
  // The root cgroup itself.
  CHECK(cgroup_memory_limit("0::/\n", kMountsV2, files({{"/sys/fs/cgroup/memory.max", "4096\n"}})) == 4096u);
}

TEST_CASE("host memory: cgroup v1 — the memory controller's hierarchy, found through mountinfo") {
  const std::string self = "5:cpu,cpuacct:/x\n4:memory:/process_api/job\n0::/\n";
  CHECK(cgroup_memory_limit(self, kMountsV1,
                            files({{"/sys/fs/cgroup/memory/process_api/job/memory.limit_in_bytes", "536870912\n"},
                                   {"/sys/fs/cgroup/memory/memory.limit_in_bytes", "9223372036854771712\n"}})) ==
        536870912u);
  // v1's "unlimited" is a huge number: it stays above any physical memory, so min() ignores it.
  CHECK(cgroup_memory_limit(self, kMountsV1,
                            files({{"/sys/fs/cgroup/memory/process_api/job/memory.limit_in_bytes",
                                    "9223372036854771712\n"}})) == 9223372036854771712u);
  // No memory controller mounted: no limit.
  CHECK(cgroup_memory_limit(self, "22 1 0:21 / / rw - ext4 /dev/vda1 rw\n",
                            files({{"/sys/fs/cgroup/memory/process_api/job/memory.limit_in_bytes", "1\n"}})) == UINT64_MAX);
}

TEST_CASE("host memory: mount roots, escaped mount points and unparsable files") {
  // A container's mount whose root is the container's own cgroup: the path below the root is
  // looked up under the mount point.
  const char* mounts = "40 30 0:31 /docker/abc /sys/fs/cgroup/memory ro - cgroup cgroup rw,memory\n";
  CHECK(cgroup_memory_limit("4:memory:/docker/abc\n", mounts,
                            files({{"/sys/fs/cgroup/memory/memory.limit_in_bytes", "268435456\n"}})) == 268435456u);
  // Of two v2 mounts, the one holding the process's cgroup; none holding it: no limit.
  const char* two = "30 22 0:26 /sub /mnt/sub rw - cgroup2 cgroup2 rw\n"
                    "31 22 0:26 / /sys/fs/cgroup rw - cgroup2 cgroup2 rw\n";
  const auto tree = files({{"/mnt/sub/memory.max", "1\n"}, {"/sys/fs/cgroup/ci/memory.max", "2048\n"}});
  CHECK(cgroup_memory_limit("0::/ci/job\n", two, tree) == 2048u);
  CHECK(cgroup_memory_limit("0::/sub/x\n", two, files({{"/mnt/sub/memory.max", "1024\n"}})) == 1024u);
  CHECK(cgroup_memory_limit("0::/ci/job\n", "30 22 0:26 /sub /mnt/sub rw - cgroup2 cgroup2 rw\n", tree) == UINT64_MAX);
  // A mount point with a space (mountinfo writes \040).
  const char* spaced = "30 22 0:26 / /mnt/cg\\040two rw - cgroup2 cgroup2 rw\n";
  CHECK(cgroup_memory_limit("0::/a\n", spaced, files({{"/mnt/cg two/a/memory.max", "1234\n"}})) == 1234u);
  // Garbage in a limit file, or in /proc/self/cgroup, never lowers the limit.
  CHECK(cgroup_memory_limit("0::/a\n", kMountsV2, files({{"/sys/fs/cgroup/a/memory.max", "12kB\n"}})) == UINT64_MAX);
  CHECK(cgroup_memory_limit("0::/a\n", kMountsV2, files({{"/sys/fs/cgroup/a/memory.max", ""}})) == UINT64_MAX);
  CHECK(cgroup_memory_limit("garbage\n::\n0:\n", kMountsV2, files({{"/sys/fs/cgroup/memory.max", "1\n"}})) == UINT64_MAX);
  CHECK(cgroup_memory_limit("0::/a\n", "short line\n- - -\n", files({{"/sys/fs/cgroup/a/memory.max", "1\n"}})) == UINT64_MAX);
}

TEST_CASE("host memory: this process's limit is at most the physical memory") {
  const std::uint64_t phys = physical_memory_bytes(), usable = usable_memory_bytes();
  CHECK(phys > (std::uint64_t{1} << 26));
  CHECK(usable <= phys);
  CHECK(usable > 0);
}
