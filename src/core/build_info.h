#pragma once
// What built this binary: the version (CMake's project version) and the source tree's git commit,
// for the provenance of every output (docs/metrics.md, "What the run was"). The commit comes from one
// small generated file (cmake/git_commit.cmake) so that a new commit relinks, never recompiles the rest.

namespace vtsim {

// The git commit of the source tree at build time, 12 hex digits, "-dirty" appended when tracked
// files differed from it; "unknown" when built outside a git checkout or without git.
const char* build_commit();

// CMake's project version, e.g. "0.1.0".
inline const char* build_version() { return VTSIM_VERSION; }

}  // namespace vtsim
