// vtsim vt compare: the residency policies side by side on the same traces at equal budgets —
// pop-in, latency, bandwidth — as a Markdown table (docs/vt.md "Policies compared").
#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "cli/cli_io.h"
#include "cli/commands.h"
#include "cli/trace_load.h"
#include "core/error.h"
#include "sim/run/replay.h"
#include "sim/view/scene.h"
#include "sim/trace/trace_import.h"
#include "stream/system/vt_system.h"

namespace vtsim::cli {

namespace {

struct VtCompareArgs {
  std::vector<std::string> traces;  // empty: the installed traces (default_traces_dir)
  std::string policies = throttle_policies().names(",");  // all of them
  std::vector<std::string> configs;
  std::vector<std::string> sets;
  std::string markdown, json_file;
  bool quiet = false, json = false, allow_repairs = false;
};

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::size_t b = 0;
  while (b <= s.size()) {
    const std::size_t e = std::min(s.find(',', b), s.size());
    if (e > b) out.push_back(s.substr(b, e - b));
    b = e + 1;
  }
  return out;
}

// The standard traces beside this vtsim, not in the working directory: <exe>/../share/vtsim/traces
// (an installed tree), then the source tree's traces/ (a build tree: the executable sits in
// build/, or one level deeper). Throws InputError("--traces") when none exists.
std::string default_traces_dir() {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  std::vector<fs::path> tried;
  if (!ec) {
    const fs::path bin = exe.parent_path();
    tried = {bin / ".." / "share" / "vtsim" / "traces", bin / ".." / "traces", bin / ".." / ".." / "traces"};
  }
#ifdef VTSIM_SOURCE_TRACES
  tried.emplace_back(VTSIM_SOURCE_TRACES);
#endif
  std::string list;
  for (const fs::path& p : tried) {
    if (fs::is_directory(p, ec) && fs::exists(p / "walk.csv", ec)) return fs::weakly_canonical(p, ec).string();
    list += (list.empty() ? "" : ", ") + p.lexically_normal().string();
  }
  throw InputError("--traces", "no standard traces found beside this vtsim (tried " + list + "); name trace files or directories");
}

// Files named directly, or every *.csv of a directory (sorted).
std::vector<std::string> trace_files(const std::vector<std::string>& args) {
  std::vector<std::string> out;
  for (const auto& a : args) {
    std::error_code ec;
    if (std::filesystem::is_directory(a, ec)) {
      std::vector<std::string> dir;
      for (const auto& e : std::filesystem::directory_iterator(a))
        if (e.path().extension() == ".csv") dir.push_back(e.path().string());
      std::sort(dir.begin(), dir.end());
      if (dir.empty()) throw InputError(a, "no .csv traces in this directory");
      out.insert(out.end(), dir.begin(), dir.end());
    } else {
      out.push_back(a);
    }
  }
  return out;
}

double num(const nlohmann::json& j) { return j.is_number() ? j.get<double>() : 0.0; }

void run_compare(const VtCompareArgs& a) {
  const auto policies = split(a.policies);
  if (policies.empty()) throw InputError("--policies", "no policy named");
  for (const auto& p : policies)
    if (!throttle_policies().find(p)) throw InputError("--policies", throttle_policies().unknown(p));
  check_output("--markdown", a.markdown);
  check_output("--json-file", a.json_file);
  if (a.json && (a.markdown == "-" || a.json_file == "-"))
    throw InputError("--json", "prints to stdout already: give --markdown / --json-file a file");
  const auto files = trace_files(a.traces.empty() ? std::vector<std::string>{default_traces_dir()} : a.traces);
  // The shared budget: one config for every run, the policy the only difference.
  ReplayConfig base = load_replay_config(a.configs, a.sets, VtSystem::kName);
  if (base.run.system != VtSystem::kName)  // --set run.system=... comes after the command's own system
    throw InputError("config", "field 'run.system': vt compare replays the vt system, not '" + base.run.system + "'");
  nlohmann::json rows = nlohmann::json::array();
  auto scene = make_scene_from_config(base);
  for (const auto& file : files) {
    const Trace trace = load_cli_trace(file, a.allow_repairs);
    const std::string name = std::filesystem::path(file).stem().string();
    for (const auto& policy : policies) {
      std::vector<std::string> sets = a.sets;
      sets.push_back("throttle.policy=" + policy);
      const ReplayConfig cfg = load_replay_config(a.configs, sets, VtSystem::kName);
      if (!a.quiet) progress_line(fmt::format("vt compare: {} / {}", name, policy));
      const ReplayResult r = run_replay(cfg, trace, *scene);
      const auto& s = r.summary;
      double max_bias = 0;
      int max_clamp = 0;
      for (const auto& row : r.metrics.frames()) {
        max_bias = std::max(max_bias, row.bias);
        max_clamp = std::max(max_clamp, row.clamp);
      }
      rows.push_back({{"trace", name},
                      {"policy", policy},
                      {"blurry_mean", num(s["popin"]["blurry_fraction_mean"])},
                      {"blurry_p99", num(s["popin"]["blurry_fraction_p99"])},
                      {"mean_deficit", num(s["popin"]["mean_deficit"])},
                      {"pops_per_s", num(s["popin"]["visible_pops"]) / num(s["trace"]["duration_s"])},
                      {"tts_mean", s["popin"]["time_to_sharp_s"]["mean"]},  // null: no event became sharp
                      {"tts_max", s["popin"]["time_to_sharp_s"]["max"]},
                      {"events", s["popin"]["time_to_sharp_s"]["events"]},
                      {"never_sharp", s["popin"]["time_to_sharp_s"]["never_sharp"]},
                      {"latency_p50", num(s["latency_ms"]["p50"])},
                      {"latency_p99", num(s["latency_ms"]["p99"])},
                      {"disk_MBps", num(s["bandwidth"]["disk_read_MBps"])},
                      {"upload_MBps", num(s["bandwidth"]["upload_MBps"])},
                      {"evictions", s[VtSystem::kName]["pool"]["evictions"]},
                      {"thrash", s[VtSystem::kName]["vram_thrash"]},
                      {"pressure_max", num(s[VtSystem::kName]["per_frame"]["pool_pressure"]["max"])},
                      {"max_bias", max_bias},
                      {"max_clamp", max_clamp}});
    }
  }
  if (!a.quiet) progress_done();

  std::string md;
  md += fmt::format("Pool {} pages of {}+2×{} texels, disk `{}`, upload {} tiles/frame, RAM {} MiB, view divisor {}, scene `{}`.\n\n",
                    base.vt.pool_pages, base.texture.tile_size, base.texture.border, base.disk.preset, base.upload.tiles_per_frame,
                    base.ram.capacity_MiB, base.view.divisor, base.scene.kind);
  md += "| trace | policy | blurry % mean | blurry % p99 | deficit | pops/s | sharp again s (mean / max) | latency ms p50 / p99 | "
        "disk MB/s | upload MB/s | evictions | thrash | max pressure | max bias | max clamp |\n";
  md += "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const auto& r : rows) {
    const std::string tts = !r["tts_mean"].is_number()
                                ? (r["events"].get<std::size_t>() == 0 ? std::string("–") : std::string("never"))
                                : fmt::format("{:.2f} / {:.2f}{}", r["tts_mean"].get<double>(), r["tts_max"].get<double>(),
                                              r["never_sharp"].get<std::size_t>() ? fmt::format(" ({} never)", r["never_sharp"].get<std::size_t>()) : "");
    md += fmt::format("| {} | {} | {:.2f} | {:.2f} | {:.3f} | {:.0f} | {} | {:.0f} / {:.0f} | {:.2f} | {:.2f} | {} | {} | {:.2f} | {:.2f} | {} |\n",
                      r["trace"].get<std::string>(), r["policy"].get<std::string>(), 100.0 * r["blurry_mean"].get<double>(),
                      100.0 * r["blurry_p99"].get<double>(), r["mean_deficit"].get<double>(), r["pops_per_s"].get<double>(), tts,
                      r["latency_p50"].get<double>(), r["latency_p99"].get<double>(), r["disk_MBps"].get<double>(),
                      r["upload_MBps"].get<double>(), r["evictions"].get<std::uint64_t>(), r["thrash"].get<std::uint64_t>(),
                      r["pressure_max"].get<double>(), r["max_bias"].get<double>(), r["max_clamp"].get<int>());
  }
  // Per policy, the mean over the traces.
  md += "\n| policy (mean over traces) | blurry % mean | deficit | pops/s | latency ms p99 | disk MB/s | upload MB/s | evictions |\n";
  md += "|---|---:|---:|---:|---:|---:|---:|---:|\n";
  for (const auto& p : policies) {
    double b = 0, d = 0, l = 0, disk = 0, up = 0, ev = 0, pops = 0;
    int n = 0;
    for (const auto& r : rows)
      if (r["policy"] == p) {
        b += r["blurry_mean"].get<double>();
        d += r["mean_deficit"].get<double>();
        pops += r["pops_per_s"].get<double>();
        l += r["latency_p99"].get<double>();
        disk += r["disk_MBps"].get<double>();
        up += r["upload_MBps"].get<double>();
        ev += static_cast<double>(r["evictions"].get<std::uint64_t>());
        ++n;
      }
    md += fmt::format("| {} | {:.2f} | {:.3f} | {:.0f} | {:.0f} | {:.2f} | {:.2f} | {:.0f} |\n", p, 100.0 * b / n, d / n,
                      pops / n, l / n, disk / n, up / n, ev / n);
  }
  if (!a.markdown.empty()) write_output(a.markdown, md);
  if (!a.json_file.empty()) write_output(a.json_file, rows.dump(2) + "\n");
  if (a.json) fmt::print("{}\n", rows.dump(2));
  else if (a.markdown != "-" && a.json_file != "-" && (a.markdown.empty() || !a.quiet)) fmt::print("{}", md);
}

}  // namespace

void register_vt_commands(CLI::App& app) {
  auto* vt = app.add_subcommand(VtSystem::kName, "Virtual texturing tools (docs/vt.md)");
  vt->require_subcommand(1);
  auto a = std::make_shared<VtCompareArgs>();
  auto* c = vt->add_subcommand("compare", "Replay traces under each residency policy at equal budgets; print a Markdown table");
  c->add_option("--traces", a->traces,
                "trace files or directories of *.csv (default: the standard traces installed beside vtsim, share/vtsim/traces)");
  c->add_option("--policies", a->policies, "comma-separated throttle policies")->capture_default_str();
  c->add_option("--config,-c", a->configs, "TOML config file shared by every run (docs/config.md); repeatable: files read in order, a later one overriding an earlier one's keys")->allow_extra_args(false);
  c->add_option("--set", a->sets, "override one config key for every run (repeatable)");
  c->add_option("--markdown", a->markdown, "write the table here (- for stdout)");
  c->add_option("--json-file", a->json_file, "write every run's figures as JSON here (- for stdout)");
  c->add_flag("--json", a->json, "print every run's figures as JSON instead of the table");
  c->add_flag("--quiet,-q", a->quiet, "no progress; with --markdown, nothing on stdout");
  c->add_flag("--allow-repairs", a->allow_repairs, kAllowRepairsHelp);
  c->callback([a] { run_compare(*a); });
}

}  // namespace vtsim::cli
