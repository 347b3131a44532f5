// The Python module `vtsim` (docs/python.md): replays, sweeps, traces, capacity and miss-ratio
// curves through the library entry points the CLI's commands call (run_replay,
// run_feedback_replay, replay_points, load_any_trace, clipmap_memory / vt_capacity,
// miss_ratio_curve), with results as dicts of plain values and numpy arrays.
//
// Threading: every call releases the GIL while the library works (configs, traces and replays are
// read and run without it), so concurrent.futures threads run replays in parallel. Python objects
// are only touched with the GIL held: arguments are converted before the release, results after.
//
// Errors: vtsim::InputError -> vtsim.InputError (a ValueError) carrying vtsim's message
// ("file:line: ...", "config: field 'x': ...") and `.where`; an unknown config key ->
// vtsim.ConfigKeyError (an InputError and a KeyError); std::invalid_argument -> ValueError.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <algorithm>
#include <charconv>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cache/clipmap.h"
#include "cache/page_table.h"
#include "cache/policy/access_io.h"
#include "cache/policy/belady.h"
#include "cache/policy/mrc.h"
#include "core/config_table.h"
#include "core/error.h"
#include "sim/run/feedback_replay.h"
#include "sim/run/real_replay.h"
#include "sim/run/replay.h"
#include "sim/run/replay_config.h"
#include "sim/run/systems.h"
#include "sim/sweep/sweep.h"
#include "sim/sweep/sweep_spec.h"
#include "sim/trace/trace_import.h"
#include "sim/trace/trace_io.h"
#include "stream/store/tile_store.h"

namespace py = pybind11;

namespace vtsim::python {

namespace {

// An unknown config key: vtsim.ConfigKeyError (KeyError) instead of vtsim.InputError.
class UnknownKeyError : public InputError {
 public:
  explicit UnknownKeyError(const InputError& e) : InputError(e) {}
};

PyObject* g_input_error = nullptr;  // vtsim.InputError(ValueError)
PyObject* g_key_error = nullptr;    // vtsim.ConfigKeyError(vtsim.InputError, KeyError)

void raise_input_error(PyObject* type, const InputError& e) {
  py::object exc = py::reinterpret_borrow<py::object>(type)(py::str(e.what()));
  exc.attr("where") = py::str(e.where());
  PyErr_SetObject(type, exc.ptr());
}

std::string type_name(const py::handle& v) { return py::str(py::type::handle_of(v).attr("__name__")); }

// A path argument: str or os.PathLike.
std::string path_arg(const py::handle& v, const char* arg) {
  if (py::isinstance<py::str>(v)) return v.cast<std::string>();
  if (py::hasattr(v, "__fspath__")) {
    py::object p = v.attr("__fspath__")();
    if (py::isinstance<py::str>(p)) return p.cast<std::string>();
  }
  throw InputError(arg, "expected a path (str or os.PathLike), not " + type_name(v));
}

// A Python value as a config value: bool, int, float or str.
ConfigValue config_value(const py::handle& v, const std::string& key) {
  if (py::isinstance<py::bool_>(v)) return v.cast<bool>();
  if (py::isinstance<py::int_>(v)) {
    int overflow = 0;
    const long long x = PyLong_AsLongLongAndOverflow(v.ptr(), &overflow);
    if (overflow != 0) throw InputError("config", "key '" + key + "': " + std::string(py::str(v)) + " is beyond 64 bits");
    return static_cast<std::int64_t>(x);
  }
  if (py::isinstance<py::float_>(v)) return v.cast<double>();
  if (py::isinstance<py::str>(v)) return v.cast<std::string>();
  throw InputError("config", "key '" + key + "': a bool, int, float or str, not " + type_name(v));
}

// A config dict, nested ({"run": {"system": "vt"}}) or dotted ({"run.system": "vt"}), as key-value
// pairs in the dict's order.
void flatten_config(const py::dict& d, const std::string& prefix, std::vector<std::pair<std::string, ConfigValue>>& out) {
  for (const auto& [k, v] : d) {
    if (!py::isinstance<py::str>(k)) throw InputError("config", "a key is a " + type_name(k) + ", not a str");
    const std::string key = prefix + k.cast<std::string>();
    if (py::isinstance<py::dict>(v)) flatten_config(py::reinterpret_borrow<py::dict>(v), key + ".", out);
    else out.emplace_back(key, config_value(v, key));
  }
}

// What the config arguments say, converted with the GIL held; load() builds the ReplayConfig
// without it: defaults, the TOML files in order, the dict's keys, `system`, each set line, then
// validated (load_replay_config's order, with the dict between the files and the sets).
struct ConfigArgs {
  std::vector<std::string> files;
  std::vector<std::pair<std::string, ConfigValue>> items;
  std::vector<std::string> sets;
  std::string system;

  ConfigArgs(const py::object& config, const py::object& set_lines, const py::object& sys) {
    if (py::isinstance<py::dict>(config)) flatten_config(py::reinterpret_borrow<py::dict>(config), "", items);
    else if (py::isinstance<py::list>(config) || py::isinstance<py::tuple>(config))
      for (const auto& p : config) files.push_back(path_arg(p, "config"));
    else if (!config.is_none()) files.push_back(path_arg(config, "config"));
    if (py::isinstance<py::str>(set_lines)) sets.push_back(set_lines.cast<std::string>());
    else if (py::isinstance<py::list>(set_lines) || py::isinstance<py::tuple>(set_lines)) {
      for (const auto& s : set_lines) {
        if (!py::isinstance<py::str>(s)) throw InputError("sets", "each a 'key=value' str, not " + type_name(s));
        sets.push_back(s.cast<std::string>());
      }
    } else if (!set_lines.is_none()) throw InputError("sets", "a list of 'key=value' str, not " + type_name(set_lines));
    if (py::isinstance<py::str>(sys)) system = sys.cast<std::string>();
    else if (!sys.is_none()) throw InputError("system", "a str, not " + type_name(sys));
  }

  ReplayConfig load() const {
    const auto& table = replay_config_table();
    ReplayConfig cfg;
    for (const std::string& p : files) load_toml_file(table, cfg, p);
    for (const auto& [key, value] : items) set_checked(key, [&] { table.set(cfg, key, value, "config"); });
    if (!system.empty()) table.set(cfg, "run.system", ConfigValue{system}, "system");
    for (const std::string& s : sets) {
      std::string key = s.substr(0, s.find('='));
      while (!key.empty() && key.back() == ' ') key.pop_back();
      while (!key.empty() && key.front() == ' ') key.erase(0, 1);
      set_checked(key, [&] { apply_set(table, cfg, s); });
    }
    validate(cfg);
    return cfg;
  }

 private:
  template <class F>
  static void set_checked(const std::string& key, F&& set) {
    try {
      set();
    } catch (const InputError& e) {
      if (replay_config_table().find(key) == nullptr) throw UnknownKeyError(e);
      throw;
    }
  }
};

// The summary JSON as Python values: json.loads of the text `vtsim replay --summary` writes.
py::object to_python(const nlohmann::json& j) { return py::module_::import("json").attr("loads")(j.dump()); }

void warn_all(const std::vector<std::string>& warnings) {
  if (warnings.empty()) return;
  py::object warn = py::module_::import("warnings").attr("warn");
  for (const std::string& w : warnings) warn(py::str(w), py::handle(PyExc_UserWarning), 2);
}

Trace load_trace_file(const std::string& path, bool allow_repairs, std::vector<std::string>& warnings) {
  TraceReadOptions read;
  read.allow_repairs = allow_repairs;
  TraceLoadReport rep;
  Trace t = load_any_trace(path, read, &rep);
  for (std::string& w : repair_warnings(rep.repairs, rep.poses + rep.repairs.dropped(), path)) warnings.push_back(std::move(w));
  return t;
}

template <class T, class F>
py::array_t<T> column(std::size_t n, F&& value) {
  py::array_t<T> a(static_cast<py::ssize_t>(n));
  T* p = a.mutable_data();
  for (std::size_t i = 0; i < n; ++i) p[i] = value(i);
  return a;
}

// The per-frame series: the columns of `vtsim replay --frames` (MetricsCollector::write_frames_csv),
// same names and order, as numpy arrays.
py::dict frames_dict(const MetricsCollector& m) {
  const std::vector<FrameRow>& f = m.frames();
  const std::size_t n = f.size();
  py::dict d;
  d["frame"] = column<std::int32_t>(n, [&](std::size_t i) { return f[i].frame; });
  d["t_s"] = column<double>(n, [&](std::size_t i) { return f[i].t_s; });
  d["clamp"] = column<std::int32_t>(n, [&](std::size_t i) { return f[i].clamp; });
  d["bias"] = column<double>(n, [&](std::size_t i) { return f[i].bias; });
  d["measured"] = column<bool>(n, [&](std::size_t i) { return f[i].measured; });
  d["samples"] = column<std::uint32_t>(n, [&](std::size_t i) { return f[i].samples; });
  d["blurry_fraction"] = column<double>(n, [&](std::size_t i) {
    return f[i].samples ? static_cast<double>(f[i].blurry) / f[i].samples : 0.0;
  });
  d["mean_deficit"] = column<double>(n, [&](std::size_t i) { return f[i].samples ? f[i].deficit_sum / f[i].samples : 0.0; });
  d["pops"] = column<std::uint32_t>(n, [&](std::size_t i) { return f[i].pops; });
  d["finest_needed"] = column<std::int32_t>(n, [&](std::size_t i) { return f[i].finest_needed; });
  d["event"] = column<bool>(n, [&](std::size_t i) { return f[i].event; });
  d["disk_bytes"] = column<std::uint64_t>(n, [&](std::size_t i) { return f[i].disk_bytes; });
  d["decoded_bytes"] = column<std::uint64_t>(n, [&](std::size_t i) { return f[i].decoded_bytes; });
  d["upload_bytes"] = column<std::uint64_t>(n, [&](std::size_t i) { return f[i].upload_bytes; });
  d["uploads"] = column<std::uint32_t>(n, [&](std::size_t i) { return f[i].uploads; });
  d["needs"] = column<std::uint32_t>(n, [&](std::size_t i) { return f[i].needs; });
  d["live_requests"] = column<std::uint32_t>(n, [&](std::size_t i) { return f[i].live_requests; });
  d["ram_bytes"] = column<std::uint64_t>(n, [&](std::size_t i) { return f[i].ram_bytes; });
  d["throttled_needs"] = column<std::uint32_t>(n, [&](std::size_t i) { return f[i].throttled_needs; });
  const std::vector<std::string>& sys = m.system_columns();
  for (std::size_t c = 0; c < sys.size(); ++c)
    d[py::str(sys[c])] = column<double>(n, [&](std::size_t i) { return f[i].system[c]; });
  if (std::any_of(f.begin(), f.end(), [](const FrameRow& r) { return r.produced > 0; })) {
    d["produced_tiles"] = column<std::uint32_t>(n, [&](std::size_t i) { return f[i].produced; });
    d["produce_ms"] = column<double>(n, [&](std::size_t i) { return f[i].produce_ms; });
  }
  return d;
}

py::dict replay(const py::object& config, const py::object& trace, const py::object& sets, const py::object& system,
                const py::object& feedback, const py::object& store, bool allow_repairs) {
  const ConfigArgs ca(config, sets, system);
  const std::string trace_path = trace.is_none() ? std::string() : path_arg(trace, "trace");
  const std::string feedback_path = feedback.is_none() ? std::string() : path_arg(feedback, "feedback");
  const std::string store_path = store.is_none() ? std::string() : path_arg(store, "store");
  if (trace_path.empty() == feedback_path.empty())
    throw InputError(trace_path.empty() ? "trace" : "feedback", "give a camera trace (trace=) or a feedback trace (feedback=), one of them");
  std::vector<std::string> warnings;
  ReplayResult r;
  {
    py::gil_scoped_release nogil;
    ReplayConfig cfg = ca.load();
    const Trace t = trace_path.empty() ? Trace{} : load_trace_file(trace_path, allow_repairs, warnings);
    std::optional<TileStore> st;
    ReplayEnv env;
    if (!store_path.empty()) {
      st.emplace(TileStore::open(store_path));
      for (const std::string& w : st->header().warnings) warnings.push_back(w);
      (void)bind_store_texture(cfg, *st);
      env.sizer = store_sizer(*st);
    }
    if (!feedback_path.empty()) {
      r = run_feedback_replay(cfg, feedback_path, env);
    } else {
      const std::unique_ptr<IScene> scene = make_scene_from_config(cfg);
      for (const std::string& w : scene->load_warnings()) warnings.push_back(w);
      r = run_replay(cfg, t, *scene, env);
    }
  }
  warn_all(warnings);
  py::dict out;
  out["summary"] = to_python(r.summary);
  out["frames"] = frames_dict(r.metrics);
  return out;
}

// A TOML value as sweep specs write a point's values ("256", "0.5", "true", "\"hdd\"").
py::object toml_scalar(const std::string& v) {
  if (v.size() >= 2 && v.front() == '"' && v.back() == '"') return py::str(v.substr(1, v.size() - 2));
  if (v == "true" || v == "false") return py::bool_(v == "true");
  const char* end = v.data() + v.size();
  std::int64_t i = 0;
  if (auto [p, ec] = std::from_chars(v.data(), end, i); ec == std::errc() && p == end) return py::int_(i);
  double d = 0;
  if (auto [p, ec] = std::from_chars(v.data(), end, d); ec == std::errc() && p == end) return py::float_(d);
  return py::str(v);
}

py::object metric_value(const nlohmann::json* v) {
  if (!v || v->is_null()) return py::none();
  if (v->is_boolean()) return py::bool_(v->get<bool>());
  if (v->is_number_unsigned()) return py::int_(v->get<std::uint64_t>());
  if (v->is_number_integer()) return py::int_(v->get<std::int64_t>());
  if (v->is_number()) return py::float_(v->get<double>());
  if (v->is_string()) return py::str(v->get<std::string>());
  return py::str(v->dump());  // an object or array: its JSON text (rows.csv writes the same)
}

// One row per (config, trace), in row order, with rows.csv's columns as plain Python values.
py::list sweep(const py::object& spec_arg, const py::object& metrics, int jobs) {
  const std::string path = path_arg(spec_arg, "spec");
  std::optional<std::vector<std::string>> metric_list;
  if (!metrics.is_none()) {
    if (!py::isinstance<py::list>(metrics) && !py::isinstance<py::tuple>(metrics))
      throw InputError("metrics", "a list of dotted summary paths, not " + type_name(metrics));
    metric_list.emplace();
    for (const auto& m : metrics) {
      if (!py::isinstance<py::str>(m)) throw InputError("metrics", "each a str, not " + type_name(m));
      metric_list->push_back(m.cast<std::string>());
    }
  }
  if (jobs < 0) throw InputError("jobs", "must be >= 0 (0: one per core)");
  std::vector<std::string> warnings;
  SweepSpec spec;
  std::vector<Trace> traces;
  std::vector<nlohmann::json> rows;
  {
    py::gil_scoped_release nogil;
    spec = load_sweep_spec(path);
    if (metric_list) {
      spec.metrics = *metric_list;
      spec.metrics_line = 0;
    }
    traces = load_sweep_traces(spec, &warnings);
    check_sweep_metrics(spec, traces);
    std::vector<int> configs(spec.points.size());
    for (std::size_t i = 0; i < configs.size(); ++i) configs[i] = static_cast<int>(i);
    for (auto& per_config : replay_points(spec, traces, configs, jobs))
      for (nlohmann::json& row : per_config) rows.push_back(std::move(row));
    std::sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a["row"] < b["row"]; });
  }
  warn_all(warnings);
  py::list out;
  for (const nlohmann::json& r : rows) {
    py::dict d;
    const std::size_t t = r["trace"].get<std::size_t>();
    d["row"] = r["row"].get<std::size_t>();
    d["config"] = r["config"].get<int>();
    d["trace"] = t;
    d["trace_name"] = traces[t].name;
    for (const std::string& k : spec.axis_keys) {
      const auto it = r["values"].find(k);
      d[py::str(k)] = it == r["values"].end() ? py::object(py::none()) : toml_scalar(it->get<std::string>());
    }
    const bool ok = r["status"] == "ok";
    d["status"] = r["status"].get<std::string>();
    for (const std::string& m : spec.metrics) d[py::str(m)] = ok ? metric_value(summary_path(r["summary"], m)) : py::object(py::none());
    d["error"] = ok ? py::object(py::none()) : py::object(py::str(r.value("error", std::string())));
    out.append(std::move(d));
  }
  return out;
}

py::dict load_trace(const py::object& path_obj, bool allow_repairs) {
  const std::string path = path_arg(path_obj, "path");
  std::vector<std::string> warnings;
  Trace t;
  {
    py::gil_scoped_release nogil;
    t = load_trace_file(path, allow_repairs, warnings);
  }
  warn_all(warnings);
  const std::vector<Pose>& p = t.poses;
  const std::size_t n = p.size();
  py::array_t<double> pos({static_cast<py::ssize_t>(n), py::ssize_t{3}});
  py::array_t<double> q({static_cast<py::ssize_t>(n), py::ssize_t{4}});
  auto pw = pos.mutable_unchecked<2>();
  auto qw = q.mutable_unchecked<2>();
  for (std::size_t i = 0; i < n; ++i) {
    const auto s = static_cast<py::ssize_t>(i);
    for (py::ssize_t k = 0; k < 3; ++k) pw(s, k) = p[i].pos_m[static_cast<int>(k)];
    qw(s, 0) = p[i].q.w, qw(s, 1) = p[i].q.x, qw(s, 2) = p[i].q.y, qw(s, 3) = p[i].q.z;
  }
  py::dict d;
  d["name"] = t.name;
  d["source_path"] = t.source_path;
  d["image_width"] = t.image_width;
  d["image_height"] = t.image_height;
  d["t_s"] = column<double>(n, [&](std::size_t i) { return p[i].t_s; });
  d["pos_m"] = pos;
  d["q_wxyz"] = q;
  d["vfov_deg"] = column<double>(n, [&](std::size_t i) { return p[i].vfov_deg; });
  return d;
}

// What a config's texture costs: a clipmap's stack and pyramid against a full mip chain, or a
// virtual texture's pages, page table and the pool a screen needs (Yao 2011 §2). The config's
// texture.* and clipmap.clipsize, as `vtsim capacity -c` reads them.
py::dict capacity(const py::object& config, const py::object& sets, const std::string& system, const py::object& screen,
                  double overdraw, double redundancy, double texels_per_pixel) {
  // The systems whose capacity report is the window stack or the page pool (SystemCaps): not the
  // produced terrain's (`vtsim capacity --system terrain`).
  const SystemInfo* info = streaming_systems().find(system);
  if (!info) throw InputError("system", streaming_systems().unknown(system));
  const CapacityReport report = info->caps.capacity;
  if (report != CapacityReport::window_stack && report != CapacityReport::page_pool)
    throw InputError("system", "'" + system + "': capacity() reports a clipmap's window stack or a virtual texture's page pool");
  int sw = 1920, sh = 1080;
  if (!screen.is_none()) {
    if (!py::isinstance<py::tuple>(screen) && !py::isinstance<py::list>(screen))
      throw InputError("screen", "a (width, height) pair, not " + type_name(screen));
    const auto s = py::reinterpret_borrow<py::sequence>(screen);
    if (s.size() != 2 || !py::isinstance<py::int_>(s[0]) || !py::isinstance<py::int_>(s[1]))
      throw InputError("screen", "a (width, height) pair of int");
    sw = s[0].cast<int>(), sh = s[1].cast<int>();
    if (sw <= 0 || sh <= 0 || sw > 65536 || sh > 65536) throw InputError("screen", "each side in [1, 65536] pixels");
  }
  const std::pair<const char*, double> factors[] = {{"overdraw", overdraw}, {"redundancy", redundancy}, {"texels_per_pixel", texels_per_pixel}};
  for (const auto& [name, v] : factors)
    if (!(v >= 1e-6 && v <= 1e6)) throw InputError(name, "must be in [1e-6, 1e6]");
  const ConfigArgs ca(config, sets, py::str(system));
  const ReplayConfig cfg = ca.load();
  const TextureConfig& tx = cfg.texture;
  double bpt = 0, disk_bpt = 0;
  for (const LayerSpec& L : tx.layers.specs) bpt += L.bytes_per_texel, disk_bpt += L.bytes_per_texel / L.compression_ratio;
  py::dict d;
  d["system"] = system;
  d["width"] = tx.width, d["height"] = tx.height, d["tile_size"] = tx.tile_size;
  d["bytes_per_texel"] = bpt;
  if (report == CapacityReport::window_stack) {
    const ClipmapMemory m = clipmap_memory({tx.width, tx.height}, tx.tile_size, cfg.clipmap.clipsize);
    d["clipsize"] = cfg.clipmap.clipsize;
    d["levels"] = m.levels, d["stack_levels"] = m.stack_levels, d["pyramid_levels"] = m.pyramid_levels;
    d["stack_texels"] = m.stack_texels, d["pyramid_texels"] = m.pyramid_texels, d["full_mip_texels"] = m.full_mip_texels;
    const double clip = static_cast<double>(m.stack_texels + m.pyramid_texels) * bpt;
    const double full = static_cast<double>(m.full_mip_texels) * bpt;
    d["clipmap_bytes"] = clip, d["full_mip_bytes"] = full, d["ratio_full_to_clipmap"] = full / clip;
    return d;
  }
  VtCapacityInput in;
  in.extent = {tx.width, tx.height};
  in.page_size = tx.tile_size;
  in.border = tx.border;
  in.bytes_per_texel = bpt;
  in.disk_bytes_per_texel = disk_bpt;
  in.screen_w = sw, in.screen_h = sh;
  in.overdraw = overdraw, in.redundancy = redundancy, in.texels_per_pixel = texels_per_pixel;
  const VtCapacity c = vt_capacity(in);
  d["border"] = tx.border;
  d["levels"] = c.levels, d["pages"] = c.pages, d["pages_level0"] = c.pages_level0;
  d["payload_texels"] = c.payload_texels, d["stored_texels"] = c.stored_texels;
  d["disk_bytes"] = c.disk_bytes, d["decoded_bytes"] = c.decoded_bytes;
  d["page_table_entries"] = c.page_table_entries, d["page_table_bytes"] = c.page_table_bytes;
  d["screen_texels"] = c.screen_texels, d["pool_pages"] = c.pool_pages, d["pool_bytes"] = c.pool_bytes;
  return d;
}

// The LRU miss-ratio curve of an access file, or of a replay's recorded accesses at one level
// (`vtsim mrc`), with Belady's misses at each size when opt.
py::dict mrc(const py::object& accesses, const py::object& trace, const py::object& config, const py::object& sets,
             const py::object& system, const std::string& level_arg, const std::string& unit, const py::object& shards,
             int sizes, bool opt) {
  const std::string acc_path = accesses.is_none() ? std::string() : path_arg(accesses, "accesses");
  const std::string trace_path = trace.is_none() ? std::string() : path_arg(trace, "trace");
  if (acc_path.empty() == trace_path.empty())
    throw InputError(trace_path.empty() ? "accesses" : "trace", "give an access file (accesses=) or a replay to record (trace=), one of them");
  MrcOptions o;
  if (unit == "pages") o.unit = MrcUnit::kPages;
  else if (unit == "bytes") o.unit = MrcUnit::kBytes;
  else throw InputError("unit", "'" + unit + "' is not pages or bytes");
  if (!shards.is_none()) {
    if (!py::isinstance<py::float_>(shards) && !py::isinstance<py::int_>(shards))
      throw InputError("shards", "a sampling rate in (0, 1], not " + type_name(shards));
    o.shards_rate = shards.cast<double>();
    if (!(o.shards_rate > 0 && o.shards_rate <= 1)) throw InputError("shards", "a sampling rate in (0, 1]");
  }
  constexpr int kMaxSizes = 10000, kMaxOptSizes = 65;  // as `vtsim mrc --sizes` (Belady: one pass per size)
  if (sizes < 2 || sizes > (opt ? kMaxOptSizes : kMaxSizes))
    throw InputError("sizes", std::to_string(sizes) + " is outside [2, " + std::to_string(opt ? kMaxOptSizes : kMaxSizes) + "]");
  o.points = static_cast<std::size_t>(sizes);
  std::optional<ConfigArgs> ca;
  if (!trace_path.empty()) ca.emplace(config, sets, system);
  else if (!config.is_none() || !sets.is_none() || !system.is_none() || !level_arg.empty())
    throw InputError("trace", "config, sets, system and level configure a replay to record: give trace=");
  std::vector<std::string> warnings;
  MissRatioCurve c;
  std::vector<std::uint64_t> belady;
  std::string level = level_arg;
  {
    py::gil_scoped_release nogil;
    AccessLog log;
    if (ca) {
      const ReplayConfig cfg = ca->load();
      const Trace t = load_trace_file(trace_path, false, warnings);
      if (level.empty()) level = std::string(streaming_systems().at(cfg.run.system).caps.mrc_level);
      if (level != "ram" && level != "pool") throw InputError("level", "'" + level + "' is not ram or pool");
      RecordedReplay r = record_accesses(cfg, t);
      if (level == "pool" && r.accesses.pool.frame_start.empty())
        throw InputError("level", "the " + cfg.run.system + " system has no page pool (use level='ram')");
      log = std::move(level == "pool" ? r.accesses.pool : r.accesses.ram);
      o.unit = level == "pool" ? MrcUnit::kPages : MrcUnit::kBytes;
    } else {
      log = read_access_file(acc_path);
    }
    c = miss_ratio_curve(log.accesses, o);
    if (opt)
      for (std::uint64_t cap : c.capacity)
        belady.push_back(o.unit == MrcUnit::kPages ? belady_min_bypass(log.accesses, cap).misses : belady_size(log.accesses, cap).misses);
  }
  warn_all(warnings);
  py::dict d;
  d["unit"] = mrc_unit_name(c.unit);
  d["method"] = c.shards_rate > 0 ? "shards_adj" : "exact";
  d["shards_rate"] = c.shards_rate;
  d["accesses"] = c.accesses, d["keys"] = c.keys, d["footprint"] = c.footprint;
  d["max_size"] = c.max_size, d["size_changes"] = c.size_changes;
  d["capacity"] = column<std::uint64_t>(c.capacity.size(), [&](std::size_t i) { return c.capacity[i]; });
  d["miss_ratio"] = column<double>(c.miss_ratio.size(), [&](std::size_t i) { return c.miss_ratio[i]; });
  if (opt)
    d["belady_miss_ratio"] = column<double>(belady.size(), [&](std::size_t i) {
      return c.accesses ? static_cast<double>(belady[i]) / static_cast<double>(c.accesses) : 0.0;
    });
  if (c.knee.found) {
    py::dict k;
    k["capacity"] = c.knee.capacity, k["miss_ratio"] = c.knee.miss_ratio;
    d["knee"] = k;
  } else {
    d["knee"] = py::none();
  }
  return d;
}

}  // namespace

}  // namespace vtsim::python

PYBIND11_MODULE(vtsim, m) {
  using namespace vtsim::python;
  namespace vp = vtsim::python;
  m.doc() = "vtsim: texture-streaming replays, sweeps, traces and cache curves (docs/python.md)";
  m.attr("__version__") = VTSIM_VERSION;
  g_input_error = PyErr_NewExceptionWithDoc("vtsim.InputError", "Bad input: vtsim's message, naming the file, line or key (.where)",
                                            PyExc_ValueError, nullptr);
  py::tuple key_bases = py::make_tuple(py::handle(g_input_error), py::handle(PyExc_KeyError));
  g_key_error = PyErr_NewExceptionWithDoc("vtsim.ConfigKeyError", "An unknown config key (an InputError and a KeyError)",
                                          key_bases.ptr(), nullptr);
  m.add_object("InputError", py::handle(g_input_error));
  m.add_object("ConfigKeyError", py::handle(g_key_error));
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const vp::UnknownKeyError& e) {
      raise_input_error(g_key_error, e);
    } catch (const vtsim::InputError& e) {
      raise_input_error(g_input_error, e);
    } catch (const std::invalid_argument& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });
  using py::arg;
  const py::none none;
  m.def("replay", &vp::replay, arg("config") = none, arg("trace") = none, arg("sets") = none, arg("system") = none,
        arg("feedback") = none, arg("store") = none, arg("allow_repairs") = false,
        "Replay a camera trace (or a feedback trace) in the simulated clock: {'summary': dict, 'frames': {column: ndarray}}");
  m.def("sweep", &vp::sweep, arg("spec"), arg("metrics") = none, arg("jobs") = 0,
        "Run a sweep spec (docs/sweep.md): one dict of plain values per (config, trace) row, rows.csv's columns");
  m.def("load_trace", &vp::load_trace, arg("path"), arg("allow_repairs") = false,
        "Read a camera trace (native CSV, TUM, EuRoC, KITTI): poses as numpy arrays");
  m.def("capacity", &vp::capacity, arg("config") = none, arg("sets") = none, arg("system") = "clipmap",
        arg("screen") = none, arg("overdraw") = 3.0, arg("redundancy") = 1.0, arg("texels_per_pixel") = 1.0,
        "Memory of a config's texture as a clipmap or a virtual texture (vtsim capacity)");
  m.def("mrc", &vp::mrc, arg("accesses") = none, arg("trace") = none, arg("config") = none, arg("sets") = none,
        arg("system") = none, arg("level") = "", arg("unit") = "pages", arg("shards") = none, arg("sizes") = 17,
        arg("opt") = false, "LRU miss-ratio curve of an access file or a replay's recorded accesses (vtsim mrc)");
}
