#include "sim/sweep/sweep_table.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <filesystem>
#include <map>
#include <sstream>

#include "core/error.h"
#include "core/input_file.h"
#include "core/registry.h"
#include "sim/sweep/sweep_spec.h"

namespace vtsim {
namespace {

constexpr std::uint64_t kTableMaxJsonBytes = 1ull << 32;

nlohmann::json table_parse(const std::string& text, const std::string& where) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(where, std::string("not valid JSON: ") + e.what());
  }
}

// A key's value in a row, as the table prints it (TOML strings without their quotes).
std::string key_value(const SweepOutputs& out, const nlohmann::json& row, const std::string& key) {
  if (key == "trace") {
    const nlohmann::json& t = out.meta["traces"][row["trace"].get<std::size_t>()];
    return t.value("name", std::string("trace ") + std::to_string(row["trace"].get<std::size_t>()));
  }
  if (key == "config") return std::to_string(row["config"].get<int>());
  if (key == "trace_file") {  // the source as the spec wrote it, without its directory
    const std::string text = out.meta["traces"][row["trace"].get<std::size_t>()].value("source", std::string());
    return text.substr(text.find_last_of('/') == std::string::npos ? 0 : text.find_last_of('/') + 1);
  }
  const auto f = row["values"].find(key);
  std::string v = f != row["values"].end() && f->is_string() ? f->get_ref<const std::string&>() : std::string();
  if (v.size() >= 2 && v.front() == '"' && v.back() == '"') v = v.substr(1, v.size() - 2);
  return v;
}

void check_key(const SweepOutputs& out, const std::string& key, const char* field) {
  std::vector<std::string> keys = {"trace", "trace_file", "config"};
  for (const auto& k : out.meta.value("axis_keys", nlohmann::json::array())) keys.push_back(k.get<std::string>());
  for (const auto& k : keys)
    if (k == key) return;
  std::vector<std::string_view> names(keys.begin(), keys.end());
  std::string msg = "'" + key + "' is not trace, trace_file, config or an axis of this sweep (axes:";
  for (std::size_t i = 3; i < keys.size(); ++i) msg += " " + keys[i];
  msg += ")";
  const std::string close = closest_name(key, names);
  if (!close.empty()) msg += "; did you mean '" + close + "'?";
  throw InputError(field, msg);
}

std::string cell_text(const nlohmann::json* v, int digits) {
  if (v == nullptr) return "n/a";
  if (v->is_number_integer() || v->is_number_unsigned()) return v->dump();
  if (v->is_number()) return fmt::format("{:.{}g}", v->get<double>(), digits);
  if (const auto* str = v->get_ptr<const std::string*>()) return *str;
  return v->dump();
}

std::string csv_cell(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

}  // namespace

SweepOutputs load_sweep_outputs(const std::string& dir) {
  namespace fs = std::filesystem;
  const fs::path sj = fs::path(dir) / "sweep.json", rj = fs::path(dir) / "rows.jsonl";
  if (!fs::exists(sj)) throw InputError(dir, "not a sweep output directory (no sweep.json; run `vtsim sweep` or `vtsim sweep merge`)");
  SweepOutputs out;
  const nlohmann::json s = table_parse(read_regular_file(sj.string(), kTableMaxJsonBytes, "not a sweep file"), sj.string());
  if (!s.is_object() || !s.contains("meta") || !s["meta"].is_object() || !s["meta"].contains("traces"))
    throw InputError(sj.string(), "not a vtsim sweep file (no meta.traces)");
  out.meta = s["meta"];
  if (!out.meta["traces"].is_array()) throw InputError(sj.string(), "meta.traces is not an array");
  for (const auto& t : out.meta["traces"])
    if (!t.is_object() || (t.contains("name") && !t["name"].is_string()) || (t.contains("source") && !t["source"].is_string()))
      throw InputError(sj.string(), "meta.traces holds an entry that is not {name, source} strings");
  if (out.meta.contains("axis_keys") && !out.meta["axis_keys"].is_array())
    throw InputError(sj.string(), "meta.axis_keys is not an array");
  for (const auto& k : out.meta.value("axis_keys", nlohmann::json::array()))
    if (!k.is_string()) throw InputError(sj.string(), "meta.axis_keys holds a non-string");
  const std::string text = read_regular_file(rj.string(), kTableMaxJsonBytes, "not a rows file");
  std::istringstream in(text);
  std::string line;
  for (std::size_t n = 1; std::getline(in, line); ++n) {
    if (line.empty()) continue;
    const std::string where = rj.string() + ":" + std::to_string(n);
    nlohmann::json r = table_parse(line, where);
    if (!r.is_object() || !r.contains("trace") || !r["trace"].is_number_unsigned() || !r.contains("config") ||
        !r["config"].is_number_integer() || !r.contains("values") || !r["values"].is_object())
      throw InputError(where, "not a sweep row (needs trace, config, values)");
    if (r.contains("status") && !r["status"].is_string()) throw InputError(where, "status is not a string");
    if (r.value("status", std::string()) == "ok" && (!r.contains("summary") || !r["summary"].is_object()))
      throw InputError(where, "an ok row without a summary object");
    if (r["trace"].get<std::size_t>() >= out.meta["traces"].size())
      throw InputError(where, fmt::format("trace {} is not in sweep.json's {} traces", r["trace"].get<std::size_t>(),
                                          out.meta["traces"].size()));
    out.rows.push_back(std::move(r));
  }
  return out;
}

std::string sweep_table(const SweepOutputs& out, const SweepTableSpec& spec) {
  if (spec.rows.empty()) throw InputError("--rows", "give at least one key (trace, config or an axis)");
  if (spec.metrics.empty()) throw InputError("--metric", "give at least one metric (a dotted summary path)");
  for (const auto& k : spec.rows) check_key(out, k, "--rows");
  const bool by_metric = spec.col == "metric";  // one table: a column per metric
  if (!by_metric) check_key(out, spec.col, "--col");
  std::vector<std::vector<std::string>> lines;  // each line's key values
  std::vector<std::string> cols;
  std::map<std::string, std::size_t> line_of, col_of;
  std::map<std::pair<std::size_t, std::size_t>, std::size_t> cell;  // -> row index
  for (std::size_t i = 0; i < out.rows.size(); ++i) {
    const nlohmann::json& r = out.rows[i];
    std::vector<std::string> vals;
    std::string line;  // the map key: values joined by a byte no TOML value or trace name holds
    for (const auto& k : spec.rows) {
      vals.push_back(key_value(out, r, k));
      line += vals.back() + '\x1f';
    }
    const std::string col = by_metric ? std::string() : key_value(out, r, spec.col);
    auto [li, lnew] = line_of.emplace(line, lines.size());
    if (lnew) lines.push_back(vals);
    auto [ci, cnew] = col_of.emplace(col, cols.size());
    if (cnew) cols.push_back(col);
    auto [at, added] = cell.emplace(std::pair{li->second, ci->second}, i);
    if (!added) {
      const nlohmann::json& other = out.rows[at->second];
      std::string differ;
      const nlohmann::json& ov = other["values"];
      for (auto it2 = r["values"].begin(); it2 != r["values"].end(); ++it2) {
        const auto o2 = ov.find(it2.key());
        if (o2 == ov.end() || *o2 != *it2) differ.append(differ.empty() ? "" : ", ").append(it2.key());
      }
      if (differ.empty() && other["trace"] != r["trace"]) differ = "trace";
      throw InputError("--rows", fmt::format("configs {} and {} both land in the cell ({}; {}): add {} to --rows or --col",
                                             other["config"].get<int>(), r["config"].get<int>(), fmt::join(vals, ", "),
                                             by_metric ? std::string("metric") : col,
                                             differ.empty() ? std::string("a key that tells them apart") : differ));
    }
  }
  for (const auto& m : spec.metrics) {
    bool any = false;
    for (const auto& r : out.rows)
      if (r.value("status", std::string()) == "ok" && r.contains("summary") && summary_path(r["summary"], m) != nullptr) any = true;
    if (!any && !out.rows.empty()) throw InputError("--metric", "'" + m + "' is in no row's summary (a dotted path such as popin.blurry_fraction_mean)");
  }
  std::string s;
  const auto value_of = [&](std::size_t l, std::size_t c, const std::string& m) {
    const auto it = cell.find({l, c});
    if (it == cell.end()) return std::string("-");
    const nlohmann::json& r = out.rows[it->second];
    return r.value("status", std::string()) == "ok" ? cell_text(summary_path(r["summary"], m), spec.digits) : std::string("error");
  };
  if (by_metric) {
    if (spec.csv) {
      s += "metric";
      for (const auto& k : spec.rows) s.append(",").append(csv_cell(k));
      s += ",value\n";
      for (const auto& m : spec.metrics)
        for (std::size_t l = 0; l < lines.size(); ++l) {
          s += csv_cell(m);
          for (const auto& v0 : lines[l]) s.append(",").append(csv_cell(v0));
          s.append(",").append(csv_cell(value_of(l, 0, m))).append("\n");
        }
      return s;
    }
    s += "|";
    for (const auto& k : spec.rows) s += " " + k + " |";
    for (const auto& m : spec.metrics) s += " " + m + " |";
    s += "\n|";
    for (std::size_t k = 0; k < spec.rows.size() + spec.metrics.size(); ++k) s += k < spec.rows.size() ? "---|" : "---:|";
    s += "\n";
    for (std::size_t l = 0; l < lines.size(); ++l) {
      s += "| " + fmt::format("{}", fmt::join(lines[l], " | ")) + " |";
      for (const auto& m : spec.metrics) s += " " + value_of(l, 0, m) + " |";
      s += "\n";
    }
    return s;
  }
  if (spec.csv) {
    s += "metric";
    for (const auto& k : spec.rows) s.append(",").append(csv_cell(k));
    s.append(",").append(csv_cell(spec.col)).append(",value\n");
  }
  for (const auto& m : spec.metrics) {
    if (!spec.csv) {
      s += "**" + m + "**\n\n|";
      for (const auto& k : spec.rows) s += " " + k + " |";
      for (const auto& c : cols) s += " " + spec.col + " = " + c + " |";
      s += "\n|";
      for (std::size_t k = 0; k < spec.rows.size() + cols.size(); ++k) s += k < spec.rows.size() ? "---|" : "---:|";
      s += "\n";
    }
    for (std::size_t l = 0; l < lines.size(); ++l) {
      if (!spec.csv) s += "| " + fmt::format("{}", fmt::join(lines[l], " | ")) + " |";
      for (std::size_t c = 0; c < cols.size(); ++c) {
        std::string v = "-";
        if (auto it = cell.find({l, c}); it != cell.end()) {
          const nlohmann::json& r = out.rows[it->second];
          v = r.value("status", std::string()) == "ok" ? cell_text(summary_path(r["summary"], m), spec.digits) : "error";
        }
        if (spec.csv) {
          std::string line = csv_cell(m);
          for (const auto& v0 : lines[l]) line.append(",").append(csv_cell(v0));
          s.append(line).append(",").append(csv_cell(cols[c])).append(",").append(csv_cell(v)).append("\n");
        } else {
          s += " " + v + " |";
        }
      }
      if (!spec.csv) s += "\n";
    }
    if (!spec.csv) s += "\n";
  }
  return s;
}

}  // namespace vtsim
