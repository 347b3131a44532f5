#include "core/host_memory.h"

#include <unistd.h>

#include <algorithm>
#include <vector>

#include "core/input_file.h"
#include "core/text.h"

namespace vtsim {

namespace {

std::vector<std::string_view> split(std::string_view s, char sep) {
  std::vector<std::string_view> out;
  for (std::size_t a = 0;;) {
    const std::size_t b = s.find(sep, a);
    out.push_back(s.substr(a, b == std::string_view::npos ? std::string_view::npos : b - a));
    if (b == std::string_view::npos) return out;
    a = b + 1;
  }
}

// mountinfo escapes space, tab, newline and backslash in paths as \ and three octal digits.
std::string unescape(std::string_view s) {
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '\\' && i + 3 < s.size() && s[i + 1] >= '0' && s[i + 1] <= '3' &&
        s[i + 2] >= '0' && s[i + 2] <= '7' && s[i + 3] >= '0' && s[i + 3] <= '7') {
      out.push_back(static_cast<char>((s[i + 1] - '0') * 64 + (s[i + 2] - '0') * 8 + (s[i + 3] - '0')));
      i += 3;
    } else {
      out.push_back(s[i]);
    }
  }
  return out;
}

// A limit file's value: a decimal byte count, or v2's "max" (none). Anything else: none.
std::uint64_t parse_limit(std::string_view text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.remove_suffix(1);
  std::uint64_t v = 0;
  if (!text::parse_whole(text, v)) return UINT64_MAX;
  return v;
}

struct Mount {
  std::string root, point;  // the cgroup directory mounted, and where
};

// Whether cgroup `path` lies at or below the mounted directory `root`.
bool covers(const std::string& root, const std::string& path) {
  return root == "/" || (path.compare(0, root.size(), root) == 0 && (path.size() == root.size() || path[root.size()] == '/'));
}

// The mount of the cgroup v2 tree (v1 == false) or of the v1 memory controller that holds cgroup
// `path`: of several, the one whose mounted directory is the deepest above it.
std::optional<Mount> find_mount(std::string_view mountinfo, bool v1, const std::string& path) {
  std::optional<Mount> best;
  for (std::string_view line : split(mountinfo, '\n')) {
    const std::vector<std::string_view> f = split(line, ' ');
    const auto dash = std::find(f.begin(), f.end(), "-");
    if (f.size() < 5 || dash == f.end() || f.end() - dash < 4) continue;
    const std::string_view fstype = dash[1], super = dash[3];
    if (v1) {
      if (fstype != "cgroup") continue;
      const std::vector<std::string_view> opts = split(super, ',');
      if (std::find(opts.begin(), opts.end(), "memory") == opts.end()) continue;
    } else if (fstype != "cgroup2") {
      continue;
    }
    Mount m{unescape(f[3]), unescape(f[4])};
    if (covers(m.root, path) && (!best || m.root.size() > best->root.size())) best = std::move(m);
  }
  return best;
}

// The least limit in `file` from the cgroup `path`'s directory up to the mount's.
std::uint64_t least_limit(const Mount& m, std::string path, const char* file, const ReadTextFile& read) {
  if (m.root != "/") path.erase(0, m.root.size());  // the part below the mounted directory
  if (path.empty()) path.push_back('/');  // not `= "/"`: GCC 12 -O3 reports a false -Wrestrict there
  std::uint64_t least = UINT64_MAX;
  for (;;) {
    const std::string dir = m.point + (path == "/" ? std::string() : path);
    if (const auto text = read(dir + "/" + file)) least = std::min(least, parse_limit(*text));
    if (path == "/") return least;
    path.erase(std::max<std::size_t>(path.rfind('/'), 1));
  }
}

}  // namespace

std::uint64_t physical_memory_bytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || page <= 0) return UINT64_MAX;
  return static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(page);
}

std::uint64_t cgroup_memory_limit(std::string_view self_cgroup, std::string_view mountinfo, const ReadTextFile& read) {
  std::uint64_t least = UINT64_MAX;
  for (std::string_view line : split(self_cgroup, '\n')) {
    // hierarchy-ID:controller-list:path (the path may itself hold ':')
    const std::size_t a = line.find(':'), b = a == std::string_view::npos ? a : line.find(':', a + 1);
    if (b == std::string_view::npos) continue;
    const std::string_view id = line.substr(0, a), controllers = line.substr(a + 1, b - a - 1);
    const std::string path(line.substr(b + 1));
    if (path.empty() || path[0] != '/') continue;
    if (id == "0" && controllers.empty()) {
      if (const auto m = find_mount(mountinfo, false, path)) least = std::min(least, least_limit(*m, path, "memory.max", read));
      continue;
    }
    const std::vector<std::string_view> c = split(controllers, ',');
    if (std::find(c.begin(), c.end(), "memory") == c.end()) continue;
    if (const auto m = find_mount(mountinfo, true, path))
      least = std::min(least, least_limit(*m, path, "memory.limit_in_bytes", read));
  }
  return least;
}

std::uint64_t usable_memory_bytes() {
  const ReadTextFile read = [](const std::string& path) -> std::optional<std::string> {
    try {
      return read_regular_file(path, std::uint64_t{1} << 20, "cgroup file");
    } catch (const std::exception&) {
      return std::nullopt;
    }
  };
  const auto self = read("/proc/self/cgroup"), mounts = read("/proc/self/mountinfo");
  const std::uint64_t cg = self && mounts ? cgroup_memory_limit(*self, *mounts, read) : UINT64_MAX;
  return std::min(physical_memory_bytes(), cg);
}

}  // namespace vtsim
