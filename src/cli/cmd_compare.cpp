// vtsim compare: metric-by-metric comparison of two summaries or two benchmark JSONs with
// per-metric tolerances; exit 0 same or within tolerance, 1 regression, 2 bad input
// (docs/compare.md). The logic is in src/sim/compare/compare.h.
#include <fmt/format.h>

#include "cli/commands.h"
#include "sim/compare/compare.h"

namespace vtsim::cli {

namespace {

struct CompareArgs {
  std::string base, now;
  std::vector<std::string> tolerances;
  std::vector<std::string> ignore;
  bool strict = false, all = false, json = false, quiet = false, wall_clock = false, exact_floats = false;
};

void run_compare_command(const CompareArgs& a) {
  CompareOptions opt;
  opt.strict = a.strict;
  opt.wall_clock = a.wall_clock;
  opt.exact_floats = a.exact_floats;
  for (const auto& path : a.tolerances) {
    auto rules = load_tolerances(path);
    opt.rules.insert(opt.rules.end(), rules.begin(), rules.end());
  }
  for (const auto& p : a.ignore) {
    ToleranceRule r;
    r.pattern = p;
    r.ignore = true;
    r.origin = "--ignore";
    opt.rules.push_back(r);
  }
  const auto base = load_json_file(a.base);
  const auto now = load_json_file(a.now);
  const CompareReport r = compare_documents(base, a.base, now, a.now, opt);
  if (a.json) fmt::print("{}\n", report_json(r, a.all, a.strict).dump(2));
  else if (!a.quiet) fmt::print("{}", format_report(r, a.all, a.strict));
  if (r.failed(a.strict)) throw Exit{kExitFailure};
}

}  // namespace

void register_compare_commands(CLI::App& app) {
  auto a = std::make_shared<CompareArgs>();
  auto* c = app.add_subcommand(
      "compare",
      "Compare two summaries (vtsim replay --summary) or two benchmark JSONs metric by metric; "
      "exit 0 same/within tolerance, 1 regression, 2 bad input");
  c->add_option("base", a->base, "the baseline JSON")->required();
  c->add_option("new", a->now, "the JSON to check against it")->required();
  c->add_option("--tolerances,-t", a->tolerances,
                "TOML file of key pattern -> abs, rel, better (lower|higher|both|info|auto), ignore; "
                "overrides the defaults (repeatable; docs/compare.md)");
  c->add_option("--ignore", a->ignore, "do not compare keys matching this pattern ('*' wildcard), e.g. 'run.*' (repeatable)");
  c->add_flag("--strict", a->strict, "also fail on improvements and on added or removed keys (baselines must be updated)");
  c->add_flag("--wall-clock", a->wall_clock,
              "also compare the wall-clock sections run.* and real_clock.* (within 25%; not compared by default: they "
              "move between runs of the same build)");
  c->add_flag("--exact-floats", a->exact_floats,
              "compare floats exactly (default: within max(1e-12, 1e-9 relative); integers are always exact)");
  c->add_flag("--all", a->all, "list every key, not only those that changed");
  c->add_flag("--json", a->json, "print the comparison as JSON");
  c->add_flag("--quiet,-q", a->quiet, "print nothing; the exit code tells");
  c->callback([a] { run_compare_command(*a); });
}

}  // namespace vtsim::cli
