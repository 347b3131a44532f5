#include "sim/report/report_identity.h"

#include <fmt/format.h>

#include "sim/report/html_escape.h"

namespace vtsim {

namespace {

std::string identity_text(const nlohmann::json& v) { return v.is_string() ? v.get<std::string>() : v.dump(); }

std::string identity_row(const std::string& k, const std::string& v) {
  return fmt::format("<tr><th>{}</th><td>{}</td></tr>\n", html_escape(k), html_escape(v));
}

}  // namespace

std::string html_run_identity(const nlohmann::json& s) {
  std::string h = "<h2>What this run was</h2>\n<table>\n";
  if (s.contains("schema")) h += identity_row("schema", identity_text(s["schema"]));
  if (s.contains("provenance")) {
    const auto& p = s["provenance"];
    h += identity_row("vtsim", fmt::format("{} (commit {}; {})", identity_text(p.value("vtsim_version", nlohmann::json("?"))),
                                           identity_text(p.value("vtsim_commit", nlohmann::json("?"))),
                                           identity_text(p.value("compiler", nlohmann::json("?")))));
    if (p.contains("machine")) {
      const auto& m = p["machine"];
      h += identity_row("machine", fmt::format("{}: {}, {} logical cores, {:.1f} GiB, {}", identity_text(m.value("hostname", nlohmann::json("?"))),
                                               identity_text(m.value("cpu", nlohmann::json("?"))), m.value("logical_cores", 0),
                                               m.value("memory_GiB", 0.0), identity_text(m.value("os", nlohmann::json("?")))));
    }
  }
  if (s.contains("trace") && s["trace"].is_object()) {
    const auto& t = s["trace"];
    const std::string path = t.value("path", std::string());
    h += identity_row("trace", fmt::format("{} ({}, {} poses over {:.3f} s)", path.empty() ? "generated: " + t.value("name", std::string()) : path,
                                           t.contains("content_hash") && t["content_hash"].is_string() ? t["content_hash"].get<std::string>() : "no file",
                                           t.value("poses", 0), t.value("poses_duration_s", 0.0)));
  }
  h += "</table>\n";
  if (s.contains("config") && s["config"].is_object()) {
    h += fmt::format("<details><summary>Effective config: {} keys, defaults included (docs/config.md)</summary>\n<table>\n",
                     s["config"].size());
    for (const auto& [k, v] : s["config"].items()) h += identity_row(k, identity_text(v));
    h += "</table></details>\n";
  }
  return h;
}

}  // namespace vtsim
