#include "sim/sweep/sweep.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <glob.h>
#include <sys/file.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <condition_variable>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <thread>
#include <utility>
#include <vector>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/hash.h"
#include "core/input_file.h"
#include "core/text.h"
#include "sim/run/provenance.h"
#include "sim/run/replay.h"
#include "sim/sweep/lockstep.h"
#include "sim/report/sweep_report.h"
#include "sim/view/mesh_import.h"
#include "sim/view/scene.h"

namespace vtsim {

namespace {

namespace fs = std::filesystem;

constexpr const char* kSchema = "vtsim.sweep/1";
// Configs stepped on one view at most: each run keeps its per-frame rows and latencies in memory
// (~100 B per frame and ~100 B per tile: a 10-minute 60 Hz trace is ~4 MB per run).
constexpr std::size_t kMaxTaskConfigs = 32;
constexpr std::uint64_t kMaxJsonBytes = 1ull << 32;

double process_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// Writes a file whole or not at all: a temporary beside it, then rename (core/atomic_file.h).
void write_atomic(const fs::path& path, const std::string& text) { write_file_atomic(path.string(), text); }

nlohmann::json parse_json(const std::string& text, const std::string& where) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(where, std::string("not valid JSON: ") + e.what());
  }
}

std::string hex64(std::uint64_t h) { return fmt::format("{:016x}", h); }

// The work of a spec in work order: trace by trace, view group by view group (in the order of
// their first config), config by config. A shard is a contiguous block of it, so it renders each
// view it touches once.
struct WorkItem {
  int trace = 0;
  int config = 0;
  int group = 0;
};

struct Task {
  std::size_t first = 0, count = 0;  // work items [first, first + count)
  int trace = 0;
  std::vector<int> configs;
};

std::vector<WorkItem> work_order(const SweepSpec& spec) {
  std::map<std::string, int> group_of_key;
  std::vector<int> group(spec.points.size());
  std::vector<std::vector<int>> members;
  for (const SweepPoint& p : spec.points) {
    auto [it, added] = group_of_key.emplace(view_key(p.cfg), static_cast<int>(members.size()));
    if (added) members.emplace_back();
    members[static_cast<std::size_t>(it->second)].push_back(p.index);
    group[static_cast<std::size_t>(p.index)] = it->second;
  }
  std::vector<WorkItem> items;
  for (int t = 0; t < static_cast<int>(spec.traces.size()); ++t)
    for (std::size_t g = 0; g < members.size(); ++g)
      for (int c : members[g]) items.push_back({t, c, static_cast<int>(g)});
  return items;
}

std::pair<std::size_t, std::size_t> shard_range(std::size_t items, const SweepShard& s) {
  const auto n = static_cast<std::size_t>(s.count), i = static_cast<std::size_t>(s.index);
  return {items * i / n, items * (i + 1) / n};
}

std::vector<Task> make_tasks(const std::vector<WorkItem>& items, std::size_t b, std::size_t e) {
  std::vector<Task> tasks;
  for (std::size_t k = b; k < e; ++k) {
    const WorkItem& w = items[k];
    const bool extend = !tasks.empty() && tasks.back().trace == w.trace && items[tasks.back().first].group == w.group &&
                        tasks.back().count < kMaxTaskConfigs;
    if (!extend) tasks.push_back({k, 0, w.trace, {}});
    tasks.back().count++;
    tasks.back().configs.push_back(w.config);
  }
  return tasks;
}

std::string part_name(const Task& t) { return fmt::format("items-{:08}-{:03}.jsonl", t.first, t.count); }

// The spec as the report and the merge need it (no costs measured yet).
nlohmann::json spec_meta(const SweepSpec& spec, const std::vector<Trace>& traces, const std::string& hash) {
  nlohmann::json m;
  m["schema"] = kSchema;
  m["name"] = spec.name;
  m["spec_hash"] = hash;
  m["metrics"] = spec.metrics;
  m["blur_bound"] = spec.blur_bound;
  m["axis_keys"] = spec.axis_keys;
  m["axes"] = nlohmann::json::array();
  for (const SweepAxis& a : spec.grid) m["axes"].push_back({{"key", a.key}, {"values", a.values}});
  m["traces"] = nlohmann::json::array();
  for (std::size_t t = 0; t < spec.traces.size(); ++t)
    m["traces"].push_back({{"trace", t},
                           {"name", traces[t].name},
                           {"source", spec.traces[t].text},
                           {"generated", spec.traces[t].generated},
                           {"poses", traces[t].poses.size()}});
  m["configs"] = nlohmann::json::array();
  for (const SweepPoint& p : spec.points) {
    nlohmann::json values = nlohmann::json::object();
    for (const auto& [k, v] : p.values) values[k] = v;
    std::uint64_t tile_bytes = 0;
    for (const LayerSpec& L : p.cfg.texture.layers.specs) tile_bytes += tile_decoded_bytes(p.cfg, L);
    m["configs"].push_back({{"config", p.index},
                            {"values", values},
                            {"system", p.cfg.run.system},
                            {"tile_bytes", tile_bytes},
                            {"ram_MiB", p.cfg.ram.capacity_MiB},
                            {"upload_tiles_per_frame", std::max<std::int64_t>(0, p.cfg.upload.tiles_per_frame)},
                            {"upload_bytes_per_frame", std::max<std::int64_t>(0, p.cfg.upload.bytes_per_frame)}});
  }
  m["rows"] = spec.points.size() * spec.traces.size();
  return m;
}

// A config's cost axes (docs/sweep.md): VRAM for tiles (the VT pool; the clipmap stack), RAM,
// the upload budget (0: no limit). From the first row that ran.
void add_costs(nlohmann::json& meta, const std::vector<nlohmann::json>& rows) {
  const std::size_t T = meta["traces"].size();
  for (auto& c : meta["configs"]) {
    const std::size_t i = c["config"].get<std::size_t>();
    double pool = 0;
    for (std::size_t t = 0; t < T; ++t) {
      const nlohmann::json& r = rows[i * T + t];
      if (r["status"] != "ok") continue;
      const nlohmann::json& s = r["summary"];
      if (s.contains("vt")) pool = s["vt"].value("pool_bytes", 0.0);
      else if (s.contains("clipmap"))
        pool = s["clipmap"].value("stack_levels", 0.0) * std::pow(s["clipmap"].value("window_tiles", 0.0), 2.0) *
               c["tile_bytes"].get<double>();
      break;
    }
    c["cost"] = {{"pool_MiB", pool / 1048576.0},
                 {"ram_MiB", c["ram_MiB"]},
                 {"upload_tiles_per_frame", c["upload_tiles_per_frame"]},
                 {"upload_MiB_per_frame", c["upload_bytes_per_frame"].get<double>() / 1048576.0}};
  }
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string o = "\"";
  for (char c : s) o += c == '"' ? std::string("\"\"") : std::string(1, c);
  return o + "\"";
}

std::string csv_value(const nlohmann::json* v) {
  if (!v || v->is_null()) return "";
  if (v->is_number_float()) return fmt::format("{}", v->get<double>());
  if (v->is_string()) return v->get<std::string>();
  return v->dump();
}

std::string rows_csv(const nlohmann::json& meta, const std::vector<nlohmann::json>& rows) {
  std::string out = "row,config,trace,trace_name";
  const auto keys = meta["axis_keys"].get<std::vector<std::string>>();
  const auto metrics = meta["metrics"].get<std::vector<std::string>>();
  for (const auto& k : keys) out.append(",").append(csv_field(k));
  out += ",status";
  for (const auto& m : metrics) out.append(",").append(csv_field(m));
  out += ",error\n";
  for (const nlohmann::json& r : rows) {
    const std::size_t t = r["trace"].get<std::size_t>();
    out += fmt::format("{},{},{},{}", r["row"].get<std::size_t>(), r["config"].get<int>(), t,
                       csv_field(meta["traces"][t]["name"].get<std::string>()));
    for (const auto& k : keys) {
      std::string v = r["values"].value(k, std::string());
      if (v.size() >= 2 && v.front() == '"' && v.back() == '"') v = v.substr(1, v.size() - 2);  // TOML string
      out.append(",").append(csv_field(v));
    }
    const bool ok = r["status"] == "ok";
    out.append(",").append(r["status"].get<std::string>());
    for (const auto& m : metrics) out.append(",").append(csv_field(ok ? csv_value(summary_path(r["summary"], m)) : std::string()));
    out.append(",").append(csv_field(ok ? std::string() : r.value("error", std::string())) + "\n");
  }
  return out;
}

// The joined outputs of a whole sweep: rows in row order (config-major), from the spec's meta.
void write_joined(nlohmann::json meta, std::vector<nlohmann::json> rows, const fs::path& out, const nlohmann::json& cost) {
  std::sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a["row"] < b["row"]; });
  add_costs(meta, rows);
  std::string jsonl;
  for (const auto& r : rows) jsonl += r.dump() + "\n";
  write_atomic(out / "rows.jsonl", jsonl);
  write_atomic(out / "rows.csv", rows_csv(meta, rows));
  write_atomic(out / "report.html", sweep_report_html(meta, rows));
  nlohmann::json s = {{"schema", kSchema}, {"provenance", build_json()}, {"meta", meta}, {"cost", cost}};
  write_atomic(out / "sweep.json", s.dump(2) + "\n");
}

// Reads a part file: its header and rows. InputError naming file:line.
struct Part {
  std::size_t first = 0, count = 0;
  std::string spec_hash, inputs;  // the header's: the sweep's identity and the task's inputs when written
  std::vector<nlohmann::json> rows;
  bool failed() const {
    return std::any_of(rows.begin(), rows.end(), [](const nlohmann::json& r) { return r.value("status", "") != "ok"; });
  }
};
// `hash` empty: a part of any identity (a resume checks its inputs itself).
Part read_part(const fs::path& path, const std::string& hash) {
  const std::string text = read_regular_file(path.string(), kMaxJsonBytes, "not a sweep part");
  Part p;
  std::size_t line = 0;
  for (std::size_t b = 0; b < text.size();) {
    std::size_t e = text.find('\n', b);
    if (e == std::string::npos) e = text.size();
    ++line;
    const std::string where = at_line(path.string(), static_cast<long long>(line));
    nlohmann::json j = parse_json(text.substr(b, e - b), where);
    if (line == 1) {
      if (!j.is_object() || !j.contains("spec_hash") || !j.contains("first") || !j.contains("count"))
        throw InputError(where, "not a sweep part header");
      if (!hash.empty() && j["spec_hash"] != hash)
        throw InputError(where, fmt::format("a part of another spec (hash {}, this spec {})", j["spec_hash"].dump(), hash));
      p.spec_hash = j["spec_hash"].is_string() ? j["spec_hash"].get<std::string>() : std::string();
      p.inputs = j.value("inputs", std::string());
      p.first = j["first"].get<std::size_t>();
      p.count = j["count"].get<std::size_t>();
    } else {
      if (!j.is_object() || !j.contains("row")) throw InputError(where, "not a sweep row");
      p.rows.push_back(std::move(j));
    }
    b = e + 1;
  }
  if (line == 0) throw InputError(path.string(), "an empty sweep part");
  if (p.rows.size() != p.count) throw InputError(path.string(), fmt::format("{} rows, its header says {}", p.rows.size(), p.count));
  return p;
}

// One writer per output directory: an exclusive flock(2) on DIR/sweep.lock, held while the sweep
// or merge runs. The kernel drops it when the process ends however it ends (a killed run leaves
// the file, never the lock). The file holds the holder's pid, for the message.
class OutputLock {
 public:
  OutputLock(const fs::path& dir, const std::string& what) {
    const fs::path f = dir / "sweep.lock";
    fd_ = ::open(f.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0) throw InputError(f.string(), std::string("cannot open the output lock: ") + std::strerror(errno));
    if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      const int err = errno;
      char buf[32] = {};
      const ssize_t n = ::pread(fd_, buf, sizeof(buf) - 1, 0);
      std::string pid = n > 0 ? std::string(buf, static_cast<std::size_t>(n)) : std::string();
      while (!pid.empty() && (pid.back() == '\n' || pid.back() == ' ')) pid.pop_back();
      ::close(fd_);
      if (err != EWOULDBLOCK) throw InputError(f.string(), std::string("cannot lock: ") + std::strerror(err));
      throw InputError(dir.string(), fmt::format("in use by another vtsim sweep or merge{} (it holds {}): wait for it to "
                                                 "end, or give {} another -o",
                                                 pid.empty() ? std::string() : " (pid " + pid + ")", f.string(), what));
    }
    const std::string pid = std::to_string(::getpid()) + "\n";
    if (::ftruncate(fd_, 0) != 0 || ::pwrite(fd_, pid.data(), pid.size(), 0) != static_cast<ssize_t>(pid.size())) {
      // The pid is only for the message; the lock holds without it.
    }
  }
  ~OutputLock() {
    if (fd_ >= 0) ::close(fd_);
  }
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;

 private:
  int fd_ = -1;
};

}  // namespace

std::vector<Trace> load_sweep_traces(const SweepSpec& spec, std::vector<std::string>* warnings) {
  std::vector<Trace> traces;
  for (const SweepTraceSource& s : spec.traces) {
    try {
      traces.push_back(load_sweep_trace(s, warnings, spec.allow_repairs));
    } catch (const InputError& e) {
      throw InputError(at_line(spec.path, s.line), fmt::format("trace '{}': {}", s.text, e.what()));
    }
    if (traces.back().poses.empty()) throw InputError(at_line(spec.path, s.line), "trace '" + s.text + "' has no poses");
  }
  return traces;
}

namespace {

// Scenes made once per scene and texture (the town is generated, a mesh loaded): shared by the
// tasks that need them, read-only while they render.
class SceneCache {
 public:
  const IScene& get(const ReplayConfig& cfg) {
    std::string key;  // every scene and texture key (a few more than the scene reads: harmless)
    for (const auto& f : replay_config_table().fields()) {
      if (f.key.rfind("scene.", 0) != 0 && f.key.rfind("texture.", 0) != 0) continue;
      key.append(f.key).append("=").append(f.get(cfg)).append("\n");
    }
    std::lock_guard<std::mutex> lock(mu_);
    auto& slot = scenes_[key];
    if (!slot) slot = make_scene_from_config(cfg);
    return *slot;
  }
  // What the scenes' readers left out (IScene::load_warnings), in key order.
  std::vector<std::string> load_warnings() {
    std::lock_guard<std::mutex> lock(mu_);
    std::vector<std::string> out;
    for (const auto& [key, scene] : scenes_)
      if (scene)  // null: the scene failed to build (that row's error)
        for (std::string& w : scene->load_warnings()) out.push_back(std::move(w));
    return out;
  }

 private:
  std::mutex mu_;
  std::map<std::string, std::unique_ptr<IScene>> scenes_;
};

// A row of rows.jsonl: the point, the trace, the summary or the error.
nlohmann::json make_row(const SweepSpec& spec, int config, int trace, LockstepResult&& res, const std::string& view_error) {
  const SweepPoint& p = spec.points[static_cast<std::size_t>(config)];
  nlohmann::json row = {{"row", static_cast<std::size_t>(config) * spec.traces.size() + static_cast<std::size_t>(trace)},
                        {"config", config},
                        {"trace", trace},
                        {"values", nlohmann::json::object()}};
  for (const auto& [k, v] : p.values) row["values"][k] = v;
  if (view_error.empty() && res.ok) {
    row["status"] = "ok";
    row["summary"] = std::move(res.summary);
  } else {
    row["status"] = "error";
    row["error"] = view_error.empty() ? res.error : view_error;
  }
  return row;
}

// Where a metric path stops resolving in a summary: "" when it resolves (an array element by any
// index: arrays differ in length between configs and traces), else why not, with the keys there.
std::string path_miss(const nlohmann::json& summary, const std::string& dotted) {
  const nlohmann::json* p = &summary;
  std::string at, rest = dotted;
  for (;;) {
    const std::size_t dot = rest.find('.');
    const std::string part = rest.substr(0, dot);
    if (p->is_array()) {
      std::size_t i = 0;
      if (!text::parse_whole(part, i)) return fmt::format("{} is a list: give an element's number", at);
      if (p->empty()) return "";
      p = &(*p)[std::min(i, p->size() - 1)];
    } else if (p->is_object()) {
      const auto it = p->find(part);
      if (it == p->end()) {
        std::string keys;
        for (const auto& [k, v] : p->items()) keys += (keys.empty() ? "" : ", ") + k;
        return fmt::format("{} has no key '{}' (keys: {})", at.empty() ? "the summary" : at, part, keys);
      }
      p = &*it;
    } else {
      return fmt::format("{} is a value, not a section", at);
    }
    at += (at.empty() ? "" : ".") + part;
    if (dot == std::string::npos) return p->is_object() || p->is_array() ? fmt::format("{} is a section, not a value", at) : "";
    rest = rest.substr(dot + 1);
  }
}

// Refuses, before any run, a metric (or tune constraint) that no row's summary could hold: a short
// replay (the first trace's first three poses) of one point of each system and metrics.opt (what
// changes the summary's keys) gives the summaries' shape. Sections a summary has only when
// the run did that work ("produce") are accepted by name. A point whose probe fails is followed by
// the next of its kind (up to four); when some kind has no shape, nothing is checked (the rows
// will say why they failed).
void check_metrics(const SweepSpec& spec, const std::vector<Trace>& traces, SceneCache& scenes) {
  if (traces.empty() || spec.points.empty()) return;
  Trace probe = traces[0];
  probe.poses.resize(std::min<std::size_t>(probe.poses.size(), 3));
  std::map<std::string, int> tries;  // per kind: -1 once a probe of it ran, else probes failed
  std::vector<nlohmann::json> shapes;
  for (const SweepPoint& p : spec.points) {
    int& t = tries[p.cfg.run.system + (p.cfg.metrics.opt ? "+opt" : "")];
    if (t < 0 || t >= 4) continue;  // a kind whose points keep failing is left to its rows
    try {
      std::vector<LockstepResult> r = run_lockstep({&p.cfg}, probe, scenes.get(p.cfg), 1);
      if (r.size() == 1 && r[0].ok) {
        shapes.push_back(std::move(r[0].summary));
        t = -1;
        continue;
      }
    } catch (const std::exception&) {
    }
    ++t;
  }
  // A kind that no probe ran could hold the metric: check only when every kind has a shape.
  for (const auto& [kind, t] : tries)
    if (t >= 0) return;
  for (const std::string& m : spec.metrics) {
    if (m.rfind("produce.", 0) == 0) continue;
    std::string miss;
    for (const nlohmann::json& s : shapes) {
      miss = path_miss(s, m);
      if (miss.empty()) break;
    }
    if (miss.empty()) continue;
    long long line = spec.metrics_line;
    std::string key = "metrics";
    for (const TuneConstraint& c : spec.tune.constraints)
      if (c.metric == m) line = c.line, key = "tune.constraints";
    throw InputError(line > 0 ? at_line(spec.path, line) : spec.path,
                     fmt::format("{}: '{}' is not a value of a replay summary: {} (docs/metrics.md)", key, m, miss));
  }
}

}  // namespace

std::vector<std::vector<nlohmann::json>> replay_points(const SweepSpec& spec, const std::vector<Trace>& traces,
                                                       const std::vector<int>& configs, int jobs) {
  std::vector<std::vector<nlohmann::json>> out(configs.size(), std::vector<nlohmann::json>(traces.size()));
  std::map<std::string, std::vector<std::size_t>> groups;
  for (std::size_t i = 0; i < configs.size(); ++i)
    groups[view_key(spec.points.at(static_cast<std::size_t>(configs[i])).cfg)].push_back(i);
  SceneCache scenes;
  const int threads = jobs > 0 ? jobs : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  for (const auto& [key, members] : groups) {
    std::vector<const ReplayConfig*> cfgs;
    for (std::size_t i : members) cfgs.push_back(&spec.points[static_cast<std::size_t>(configs[i])].cfg);
    for (std::size_t t = 0; t < traces.size(); ++t) {
      std::vector<LockstepResult> res;
      std::string view_error;
      try {
        res = run_lockstep(cfgs, traces[t], scenes.get(*cfgs[0]), threads);
      } catch (const std::exception& e) {
        view_error = e.what();
        res.assign(cfgs.size(), LockstepResult{});
      }
      for (std::size_t k = 0; k < members.size(); ++k)
        out[members[k]][t] = make_row(spec, configs[members[k]], static_cast<int>(t), std::move(res[k]), view_error);
    }
  }
  return out;
}

void check_sweep_metrics(const SweepSpec& spec, const std::vector<Trace>& traces) {
  SceneCache scenes;
  check_metrics(spec, traces, scenes);
}

namespace {

// "fnv1a64:" and the hash of a file's bytes; "missing: why" when it cannot be read (the replay
// then fails and says why; a file that appears later changes the identity).
std::string file_content_hash(const std::string& path) {
  try {
    return "fnv1a64:" + hex64(fnv1a64(read_regular_file(path, std::uint64_t{4} << 30, "more than a sweep input may hold")));
  } catch (const std::exception& e) {
    return std::string("missing: ") + e.what();
  }
}

std::string lower_ext(const std::string& path) {
  std::string e = fs::path(path).extension().string();
  if (!e.empty()) e.erase(0, 1);
  for (char& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

// The files a config's scene reads: scene.file and, through assimp, what the importer opens
// with it (an OBJ's .mtl, a glTF's buffers); the input's name ("scene.file q.obj").
std::pair<std::string, std::vector<std::string>> scene_files(const ReplayConfig& cfg) {
  if (cfg.scene.file.empty()) return {};
  std::vector<std::string> files{cfg.scene.file};
  std::string name = "scene.file " + cfg.scene.file;
  const bool assimp = cfg.scene.kind == "mesh" &&
                      (cfg.scene.mesh_loader == "assimp" || (cfg.scene.mesh_loader == "auto" && lower_ext(cfg.scene.file) != "obj"));
  if (assimp) {
    if (lower_ext(cfg.scene.file) == "obj") name += " (assimp)";
    for (std::string& f : mesh_import_files(cfg.scene.file))
      if (fs::path(f).lexically_normal() != fs::path(cfg.scene.file).lexically_normal()) files.push_back(std::move(f));
  }
  return {name, files};
}

// terrain.brush_files' files: each comma-separated name, a pattern expanded (sorted).
std::vector<std::string> brush_files(const std::string& list) {
  std::vector<std::string> out;
  for (std::size_t at = 0; at <= list.size();) {
    const std::size_t comma = std::min(list.find(',', at), list.size());
    const std::string f = list.substr(at, comma - at);
    at = comma + 1;
    if (f.empty()) continue;
    if (f.find_first_of("*?[") == std::string::npos) {
      out.push_back(f);
      continue;
    }
    glob_t g{};
    if (::glob(f.c_str(), 0, nullptr, &g) == 0)
      for (std::size_t i = 0; i < g.gl_pathc; ++i) out.emplace_back(g.gl_pathv[i]);
    globfree(&g);
  }
  return out;
}

bool any_missing(const std::vector<std::string>& files) {
  std::error_code ec;
  return std::any_of(files.begin(), files.end(), [&](const std::string& f) { return !fs::is_regular_file(f, ec); });
}

std::string files_hash(const std::vector<std::string>& files) {
  std::uint64_t h = fnv1a64("files");
  // By file name, not path: shards started from other directories agree.
  for (const std::string& f : files) h = fnv1a64(fs::path(f).filename().string() + "=" + file_content_hash(f) + "\n", h);
  return hex64(h);
}

}  // namespace

std::string SweepIdentity::task_inputs(int trace, const std::vector<int>& configs) const {
  std::set<std::string> names{"build", "base config"};
  for (const auto& [name, v] : inputs.items())
    if (name.rfind("trace ", 0) == 0 && v.value("trace", -1) == trace) names.insert(name);
  for (int c : configs)
    for (const std::string& n : config_inputs.at(static_cast<std::size_t>(c))) names.insert(n);
  std::uint64_t h = fnv1a64("task");
  for (const std::string& n : names)
    if (inputs.contains(n)) h = fnv1a64(n + "=" + inputs[n]["hash"].get<std::string>() + "\n", h);
  return hex64(h);
}

SweepIdentity sweep_identity(const SweepSpec& spec, const std::vector<Trace>& traces) {
  SweepIdentity id;
  std::uint64_t h = fnv1a64(kSchema);
  h = fnv1a64(spec.name + "\n", h);
  for (const SweepPoint& p : spec.points)
    for (const auto& [k, v] : p.values) h = fnv1a64(fmt::format("{}:{}={}\n", p.index, k, v), h);
  for (const std::string& m : spec.metrics) h = fnv1a64(m + "\n", h);
  h = fnv1a64(fmt::format("traces {}\n", spec.traces.size()), h);
  id.structure = hex64(h);

  // The build: rows are a function of the binary as much as of the inputs (its version and
  // commit; "-dirty" builds of one commit cannot be told apart, docs/sweep.md).
  const nlohmann::json build = build_json();
  const std::string build_what = fmt::format("vtsim {} commit {} ({})", build.value("vtsim_version", std::string("?")),
                                             build.value("vtsim_commit", std::string("?")), build.value("compiler", std::string("?")));
  id.inputs["build"] = {{"hash", hex64(fnv1a64(build.dump()))}, {"what", build_what}};
  // The base config: every key's effective value (the config file and the spec's `set`).
  id.inputs["base config"] = {{"hash", hex64(fnv1a64(spec.base_dump))},
                              {"what", spec.base_config.empty() ? std::string("the spec's set") : spec.base_config}};
  for (std::size_t t = 0; t < spec.traces.size(); ++t) {
    // A trace is its content: its poses as loaded (what the replays see), exactly; not the path
    // it was read from (shards started from other directories name it differently).
    std::uint64_t th = fnv1a64("trace");
    for (const Pose& p : traces[t].poses)
      th = fnv1a64(std::string_view(reinterpret_cast<const char*>(&p), sizeof(Pose)), th);
    th = fnv1a64(fmt::format("{}x{}\n", traces[t].image_width, traces[t].image_height), th);
    // Named by number, the source only shown: spec files in other directories name one file differently.
    id.inputs[fmt::format("trace {}", t)] = {{"hash", hex64(th)}, {"trace", t}, {"what", spec.traces[t].text}};
  }
  // The files each point's config names, each hashed once however many points share it.
  std::map<std::string, std::string> seen;  // input name -> hash
  for (const SweepPoint& p : spec.points) {
    std::vector<std::string> names;
    const auto [scene_name, files] = scene_files(p.cfg);
    if (!scene_name.empty()) {
      auto it = seen.find(scene_name);
      if (it == seen.end()) it = seen.emplace(scene_name, files_hash(files)).first;
      id.inputs[scene_name] = {{"hash", it->second}, {"files", files}, {"missing", any_missing(files)}};
      names.push_back(scene_name);
    }
    if (!p.cfg.terrain.brush_files.empty()) {
      const std::string name = "terrain.brush_files " + p.cfg.terrain.brush_files;
      auto it = seen.find(name);
      const std::vector<std::string> bf = brush_files(p.cfg.terrain.brush_files);
      if (it == seen.end()) it = seen.emplace(name, files_hash(bf)).first;
      id.inputs[name] = {{"hash", it->second}, {"files", bf}, {"missing", bf.empty() || any_missing(bf)}};
      names.push_back(name);
    }
    id.config_inputs.push_back(std::move(names));
  }
  for (const auto& [name, v] : id.inputs.items()) h = fnv1a64(name + "=" + v["hash"].get<std::string>() + "\n", h);
  id.hash = hex64(h);
  return id;
}

std::string sweep_spec_hash(const SweepSpec& spec, const std::vector<Trace>& traces) {
  return sweep_identity(spec, traces).hash;
}

SweepShard parse_shard(const std::string& text, const std::string& where) {
  SweepShard s;
  if (text == "slurm") {
    const char* id = std::getenv("SLURM_ARRAY_TASK_ID");
    const char* count = std::getenv("SLURM_ARRAY_TASK_COUNT");
    const char* min = std::getenv("SLURM_ARRAY_TASK_MIN");
    if (!id || !count)
      throw InputError(where, "'slurm': SLURM_ARRAY_TASK_ID and SLURM_ARRAY_TASK_COUNT are not set (run it in `sbatch --array`)");
    const long long i = std::atoll(id) - (min ? std::atoll(min) : 0), n = std::atoll(count);
    if (n < 1 || i < 0 || i >= n)
      throw InputError(where, fmt::format("'slurm': task {} of {} (SLURM_ARRAY_TASK_ID - SLURM_ARRAY_TASK_MIN must be in [0, "
                                          "SLURM_ARRAY_TASK_COUNT); use a contiguous --array=0-{})",
                                          i, n, n > 0 ? n - 1 : 0));
    return {static_cast<int>(i), static_cast<int>(n)};
  }
  const std::size_t slash = text.find('/');
  char* end = nullptr;
  const long long i = slash == std::string::npos ? -1 : std::strtoll(text.c_str(), &end, 10);
  const bool i_ok = slash != std::string::npos && end == text.c_str() + slash && slash > 0;
  const long long n = i_ok ? std::strtoll(text.c_str() + slash + 1, &end, 10) : 0;
  const bool n_ok = i_ok && *end == '\0' && slash + 1 < text.size();
  if (!n_ok || n < 1 || n > 100000 || i < 0 || i >= n)
    throw InputError(where, "'" + text + "' is not I/N with 0 <= I < N (e.g. 0/4), or slurm");
  s.index = static_cast<int>(i);
  s.count = static_cast<int>(n);
  return s;
}

namespace {

// The inputs that changed since an existing output directory was written (its shard.json, if
// any): a directory of another spec or shard is refused, changed inputs are unless rerun_changed.
std::set<std::string> changed_inputs(const fs::path& shard_file, const SweepIdentity& id, const SweepOptions& opts) {
  const std::string& hash = id.hash;
  std::set<std::string> changed;
  if (!fs::exists(shard_file)) return changed;
  const nlohmann::json old = parse_json(read_regular_file(shard_file.string(), kMaxJsonBytes, "not a shard file"),
                                        shard_file.string());
  if (old.value("spec_hash", std::string()) != hash) {
    if (old.value("structure_hash", std::string()) != id.structure || !old.contains("inputs") || !old["inputs"].is_object())
      throw InputError(shard_file.string(), fmt::format("holds a sweep of another spec (hash {}, this spec {}): give another "
                                                        "-o, or delete the directory",
                                                        old.value("spec_hash", std::string("?")), hash));
    // The same spec over inputs that changed: name them; re-run what read them only when asked.
    // A file that was missing (its rows failed, and are retried anyway) is not a reason to refuse.
    std::string what;
    for (const auto& [name, v] : id.inputs.items()) {
      const nlohmann::json* o = old["inputs"].contains(name) ? &old["inputs"][name] : nullptr;
      if (o && o->is_object() && o->value("hash", std::string()) == v["hash"].get<std::string>()) continue;
      changed.insert(name);
      if (o && o->is_object() && o->value("missing", false)) continue;
      std::string detail;
      if (name == "build" && o && o->is_object())
        detail = fmt::format(" (its rows were made by {}; this is {})", o->value("what", std::string("?")), v.value("what", std::string("?")));
      else if (v.contains("trace"))
        detail = " (" + v.value("what", std::string("?")) + ")";
      what += (what.empty() ? "" : ", ") + name + detail;
    }
    for (const auto& [name, v] : old["inputs"].items())
      if (!id.inputs.contains(name)) changed.insert(name), what += (what.empty() ? "" : ", ") + name + " (no longer read)";
    if (!opts.rerun_changed && !what.empty())
      throw InputError(opts.out_dir, fmt::format("{} changed since {} was written; use a new -o or --rerun-changed "
                                                 "(re-runs the rows that read {})",
                                                 what, opts.out_dir, changed.size() == 1 ? "it" : "them"));
  }
  if (old.value("shard", -1) != opts.shard.index || old.value("count", -1) != opts.shard.count)
    throw InputError(shard_file.string(), fmt::format("holds shard {}/{} of this spec, not {}/{}", old.value("shard", -1),
                                                      old.value("count", -1), opts.shard.index, opts.shard.count));
  return changed;
}

// The tasks still to run: those whose part is on disk are done (a part is renamed into place
// whole), unless a row of it failed (retried: the failure may have been the machine's, a file
// since fixed) or an input it read changed. A part whose inputs are unchanged gets this identity's
// header. `total_frames`: the frames the tasks to run will replay (for the progress).
std::vector<const Task*> tasks_to_run(const std::vector<Task>& tasks, const fs::path& parts, const SweepSpec& spec,
                                      const std::vector<Trace>& traces, const SweepIdentity& id,
                                      const std::set<std::string>& changed, SweepRunStats& st, std::uint64_t& total_frames) {
  const std::string& hash = id.hash;
  std::error_code ec;
  std::vector<const Task*> todo;
  total_frames = 0;
  for (const Task& t : tasks) {
    const fs::path p = parts / part_name(t);
    if (fs::exists(p)) {
      Part done = read_part(p, changed.empty() ? hash : std::string());
      const bool same_task = done.first == t.first && done.count == t.count;
      const bool inputs_same = done.inputs == id.task_inputs(t.trace, t.configs);
      if (same_task && inputs_same && !done.failed()) {
        if (done.spec_hash != hash) {
          std::string text = nlohmann::json({{"spec_hash", hash}, {"inputs", done.inputs}, {"first", t.first}, {"count", t.count}}).dump() + "\n";
          for (const auto& r : done.rows) text += r.dump() + "\n";
          write_atomic(p, text);
        }
        st.rows_skipped += t.count;
        continue;
      }
      if (same_task && done.failed()) st.rows_retried += t.count;
      else if (same_task) st.rows_changed += t.count;
      fs::remove(p, ec);  // a stale part never joins the outputs, even if this run is killed
    }
    todo.push_back(&t);
    const Trace& tr = traces[static_cast<std::size_t>(t.trace)];
    const double fps = spec.points[static_cast<std::size_t>(t.configs[0])].cfg.run.fps;
    const double dur = tr.poses.back().t_s - tr.poses.front().t_s;
    total_frames += t.count * static_cast<std::uint64_t>(fps > 0 ? dur * fps + 1 : static_cast<double>(tr.poses.size()));
  }
  return todo;
}

}  // namespace

SweepRunStats run_sweep(const SweepSpec& spec, const SweepOptions& opts) {
  const auto wall0 = std::chrono::steady_clock::now();
  const double cpu0 = process_cpu_s();
  std::vector<std::string> trace_warnings;
  const std::vector<Trace> traces = load_sweep_traces(spec, &trace_warnings);
  const SweepIdentity id = sweep_identity(spec, traces);
  const std::string& hash = id.hash;
  SceneCache scenes;
  check_metrics(spec, traces, scenes);  // before anything is written
  const fs::path out(opts.out_dir);
  const fs::path parts = out / "parts";
  std::error_code ec;
  make_output_dir("-o", opts.out_dir);  // the last level only: a missing parent is refused
  const OutputLock out_lock(out, "this sweep");
  fs::create_directory(parts, ec);
  if (ec) throw InputError(parts.string(), "cannot create the directory: " + ec.message());
  const fs::path shard_file = out / "shard.json";
  const std::set<std::string> changed = changed_inputs(shard_file, id, opts);  // since the directory was written
  const nlohmann::json meta = spec_meta(spec, traces, hash);
  const std::vector<WorkItem> items = work_order(spec);
  const auto [b, e] = shard_range(items.size(), opts.shard);
  const std::vector<Task> tasks = make_tasks(items, b, e);
  nlohmann::json shard = {{"schema", kSchema}, {"spec_hash", hash}, {"structure_hash", id.structure}, {"inputs", id.inputs},
                          {"shard", opts.shard.index}, {"count", opts.shard.count}, {"items", {b, e}}, {"complete", false},
                          {"meta", meta}};

  // Restart (tasks_to_run): the parts on disk that are still good are kept.
  for (const auto& f : fs::directory_iterator(parts))
    if (is_atomic_temp_name(f.path().filename().string()) || f.path().extension() == ".tmp")  // ".tmp": older builds' name
      fs::remove(f.path(), ec);
  SweepRunStats st;
  st.input_warnings = std::move(trace_warnings);
  st.rows = e - b;
  std::uint64_t total_frames = 0;
  const std::vector<const Task*> todo = tasks_to_run(tasks, parts, spec, traces, id, changed, st, total_frames);
  write_atomic(shard_file, shard.dump(2) + "\n");
  st.tasks = todo.size();

  const int jobs = opts.jobs > 0 ? opts.jobs : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  const int parallel = std::max(1, std::min<int>(jobs, static_cast<int>(todo.size())));
  const int team = std::max(1, jobs / parallel);
  std::atomic<std::size_t> next{0}, rows_done{0}, failed{0};
  std::atomic<std::uint64_t> frames_done{0};
  std::atomic<double> replayed_s{0.0};
  std::mutex err_mu;
  std::exception_ptr first_error;
  const auto worker = [&] {
    for (;;) {
      const std::size_t k = next.fetch_add(1);
      if (k >= todo.size()) return;
      const Task& t = *todo[k];
      try {
        const Trace& trace = traces[static_cast<std::size_t>(t.trace)];
        std::vector<const ReplayConfig*> cfgs;
        for (int c : t.configs) cfgs.push_back(&spec.points[static_cast<std::size_t>(c)].cfg);
        std::vector<LockstepResult> res;
        std::string scene_error;
        try {
          res = run_lockstep(cfgs, trace, scenes.get(*cfgs[0]), team, &frames_done);
        } catch (const std::exception& ex) {
          scene_error = ex.what();  // the view itself failed (scene, trace): every row of the task says so
          res.assign(cfgs.size(), LockstepResult{});
        }
        std::string text = nlohmann::json({{"spec_hash", hash}, {"inputs", id.task_inputs(t.trace, t.configs)},
                                           {"first", t.first}, {"count", t.count}}).dump() + "\n";
        for (std::size_t i = 0; i < t.configs.size(); ++i) {
          nlohmann::json row = make_row(spec, t.configs[i], t.trace, std::move(res[i]), scene_error);
          if (row["status"] == "ok") replayed_s.fetch_add(row["summary"]["trace"]["duration_s"].get<double>());
          else failed.fetch_add(1);
          text += row.dump() + "\n";
        }
        write_atomic(parts / part_name(t), text);
        rows_done.fetch_add(t.count);
      } catch (...) {
        std::lock_guard<std::mutex> lock(err_mu);
        if (!first_error) first_error = std::current_exception();
        next.store(todo.size());  // stop claiming: the output directory is not writable, ...
      }
    }
  };
  std::vector<std::thread> pool;
  if (opts.progress && !todo.empty()) {
    // Every worker on a thread of its own; this thread reports progress about once a second.
    std::mutex mu;
    std::condition_variable cv;
    int finished = 0;
    for (int i = 0; i < parallel; ++i)
      pool.emplace_back([&] {
        worker();
        std::lock_guard<std::mutex> lock(mu);
        ++finished;
        cv.notify_one();
      });
    std::unique_lock<std::mutex> lock(mu);
    while (!cv.wait_for(lock, std::chrono::seconds(1), [&] { return finished == parallel; })) {
      const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
      const double frac = total_frames ? static_cast<double>(frames_done.load()) / static_cast<double>(total_frames) : 1.0;
      opts.progress(st.rows_skipped + rows_done.load(), st.rows, frac, el, frac > 0 ? el * (1 - frac) / frac : 0.0);
    }
  } else {
    for (int i = 1; i < parallel; ++i) pool.emplace_back(worker);
    worker();
  }
  for (auto& th : pool) th.join();
  if (first_error) std::rethrow_exception(first_error);
  // And once when every row is done (also a run under a second, or one that found everything
  // done), so that a log shows how the run ended.
  if (opts.progress)
    opts.progress(st.rows_skipped + rows_done.load(), st.rows, 1.0,
                  std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count(), 0.0);

  st.rows_failed = failed.load();
  for (std::string& w : scenes.load_warnings()) st.input_warnings.push_back(std::move(w));
  st.views_rendered = todo.size();
  st.replayed_s = replayed_s.load();
  st.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  st.cpu_s = process_cpu_s() - cpu0;
  const nlohmann::json cost = {{"wall_s", st.wall_s},       {"cpu_s", st.cpu_s},     {"jobs", jobs},
                               {"rows_run", st.rows - st.rows_skipped}, {"rows_skipped", st.rows_skipped},
                               {"views_rendered", st.views_rendered}, {"replayed_s", st.replayed_s}};
  shard["complete"] = true;
  shard["cost"] = cost;
  write_atomic(shard_file, shard.dump(2) + "\n");
  if (opts.shard.count == 1) {
    std::vector<nlohmann::json> rows;
    for (const Task& t : tasks) {
      Part p = read_part(parts / part_name(t), hash);
      for (auto& r : p.rows) rows.push_back(std::move(r));
    }
    write_joined(meta, std::move(rows), out, cost);
  }
  return st;
}

void merge_sweep(const std::vector<std::string>& shard_dirs, const std::string& out_dir) {
  if (shard_dirs.empty()) throw InputError("merge", "no shard directories given");
  nlohmann::json meta;
  std::string hash;
  int count = -1;
  std::map<int, std::string> seen;
  std::vector<nlohmann::json> rows;
  std::vector<std::pair<std::size_t, std::size_t>> covered;  // item ranges of the parts
  std::map<std::size_t, std::pair<std::size_t, std::string>> shard_items;  // first item -> end, directory
  nlohmann::json cost = {{"wall_s", 0.0}, {"cpu_s", 0.0}, {"shards", nlohmann::json::array()}};
  for (const std::string& d : shard_dirs) {
    const fs::path f = fs::path(d) / "shard.json";
    if (!fs::exists(f)) throw InputError(d, "not a sweep shard directory (no shard.json)");
    const nlohmann::json s = parse_json(read_regular_file(f.string(), kMaxJsonBytes, "not a shard file"), f.string());
    if (s.value("schema", std::string()) != kSchema) throw InputError(f.string(), std::string("not a ") + kSchema + " shard");
    const std::string h = s.value("spec_hash", std::string());
    if (hash.empty()) hash = h, meta = s["meta"], count = s.value("count", -1);
    if (h != hash)
      throw InputError(f.string(), fmt::format("a shard of another spec (hash {}; {} has {})", h, seen.begin()->second, hash));
    if (s.value("count", -1) != count)
      throw InputError(f.string(), fmt::format("a shard of {} (the others are of {})", s.value("count", -1), count));
    const int index = s.value("shard", -1);
    if (auto [it, added] = seen.emplace(index, d); !added)
      throw InputError(f.string(), fmt::format("shard {}/{} again (also in {})", index, count, it->second));
    if (!s.value("complete", false))
      throw InputError(f.string(), fmt::format("shard {}/{} is incomplete (run it again with the same -o to finish)", index, count));
    if (s.contains("cost")) {
      cost["wall_s"] = cost["wall_s"].get<double>() + s["cost"].value("wall_s", 0.0);
      cost["cpu_s"] = cost["cpu_s"].get<double>() + s["cost"].value("cpu_s", 0.0);
      cost["shards"].push_back(s["cost"]);
    }
    const auto range = s["items"].get<std::vector<std::size_t>>();
    if (range[1] > range[0]) shard_items[range[0]] = {range[1], d};  // an empty shard holds no item
    for (const auto& pf : fs::directory_iterator(fs::path(d) / "parts")) {
      if (pf.path().extension() != ".jsonl") continue;
      Part p = read_part(pf.path(), hash);
      if (p.first < range[0] || p.first + p.count > range[1])
        throw InputError(pf.path().string(), fmt::format("items {}..{} lie outside shard {}'s {}..{}", p.first,
                                                         p.first + p.count, index, range[0], range[1]));
      covered.emplace_back(p.first, p.first + p.count);
      for (auto& r : p.rows) rows.push_back(std::move(r));
    }
  }
  for (int i = 0; i < count; ++i)
    if (!seen.count(i)) throw InputError("merge", fmt::format("shard {}/{} is missing", i, count));
  std::sort(covered.begin(), covered.end());
  const std::size_t R = meta["rows"].get<std::size_t>();
  // A gap or an overlap names the shard directory whose items it falls in (its parts were
  // removed or copied in from elsewhere although its shard.json says complete).
  constexpr const char* kRedo = "(run that shard again with the same -o: it redoes what is missing)";
  const auto dir_of = [&](std::size_t item) {
    auto it = shard_items.upper_bound(item);
    return it == shard_items.begin() || item >= std::prev(it)->second.first ? std::string("merge") : std::prev(it)->second.second;
  };
  std::size_t at = 0;
  for (const auto& [b, e] : covered) {
    if (b > at) throw InputError(dir_of(at), fmt::format("work items {}..{} are missing from parts/ {}", at, b, kRedo));
    if (b < at) throw InputError(dir_of(b), fmt::format("work items {}..{} are in two parts of parts/", b, at));
    at = e;
  }
  if (at != R) throw InputError(dir_of(at), fmt::format("work items {}..{} are missing from parts/ {}", at, R, kRedo));
  make_output_dir("-o", out_dir);
  const OutputLock out_lock(out_dir, "the merge");
  write_joined(meta, std::move(rows), fs::path(out_dir), cost);
}

}  // namespace vtsim
