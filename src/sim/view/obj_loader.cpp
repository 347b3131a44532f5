// Wavefront OBJ reader for the mesh scene: geometry and texture coordinates only.
#include <charconv>
#include <cmath>
#include <string>
#include <string_view>
#include <vector>

#include <glm/geometric.hpp>

#include "core/error.h"
#include "core/input_file.h"
#include "sim/trace/trace_text.h"
#include "sim/view/mesh.h"

namespace vtsim {

namespace {

constexpr double kMaxCoord = 1e12;  // metres (or UV units): beyond any scene, far below overflow

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

// Next whitespace-separated token of `s` from `pos`, or an empty view at the end.
std::string_view next_token(std::string_view s, std::size_t& pos) {
  while (pos < s.size() && is_space(s[pos])) ++pos;
  const std::size_t b = pos;
  while (pos < s.size() && !is_space(s[pos])) ++pos;
  return s.substr(b, pos - b);
}

double parse_number(std::string_view tok, const std::string& where, const char* what) {
  double x = 0.0;
  const char* first = tok.data();
  if (!tok.empty() && tok[0] == '+') ++first;  // from_chars rejects a leading '+'
  const auto [ptr, ec] = std::from_chars(first, tok.data() + tok.size(), x);
  if (ec == std::errc::result_out_of_range && ptr == tok.data() + tok.size())
    throw InputError(where, std::string(what) + " " + trace_text::quote(tok) + " is not a finite number within ±1e12");
  if (ec != std::errc() || ptr != tok.data() + tok.size() || tok.empty())
    throw InputError(where, std::string("malformed ") + what + " " + trace_text::quote(tok));
  if (!std::isfinite(x) || std::fabs(x) > kMaxCoord)
    throw InputError(where, std::string(what) + " " + trace_text::quote(tok) + " is not a finite number within ±1e12");
  return x;
}

// Resolves a 1-based or negative (relative) OBJ index against `count` items defined so far.
std::uint32_t resolve_index(std::string_view tok, std::size_t count, const std::string& where, const char* what) {
  long long idx = 0;
  const auto [ptr, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), idx);
  if (ec != std::errc() || ptr != tok.data() + tok.size() || tok.empty())
    throw InputError(where, std::string("malformed ") + what + " index " + trace_text::quote(tok));
  const long long n = static_cast<long long>(count);
  long long r;
  if (idx > 0) r = idx - 1;
  else if (idx < 0) r = n + idx;
  else throw InputError(where, std::string(what) + " index 0 (OBJ indices start at 1)");
  if (r < 0 || r >= n)
    throw InputError(where, std::string(what) + " index " + std::string(tok) + " is out of range (" +
                                std::to_string(n) + " defined so far)");
  return static_cast<std::uint32_t>(r);
}

}  // namespace

Mesh parse_obj(const std::string& text, const std::string& name, ObjStats* stats_out, const ObjLimits& limits) {
  Mesh m;
  ObjStats st;
  std::vector<std::uint32_t> fp;
  std::vector<std::int32_t> ft;
  std::size_t line_begin = 0;
  long long line_no = 0;
  while (line_begin < text.size()) {
    std::size_t line_end = text.find('\n', line_begin);
    if (line_end == std::string::npos) line_end = text.size();
    std::string_view line(text.data() + line_begin, line_end - line_begin);
    line_begin = line_end + 1;
    ++line_no;
    if (const std::size_t hash = line.find('#'); hash != std::string_view::npos) line = line.substr(0, hash);
    while (!line.empty() && is_space(line.back())) line.remove_suffix(1);
    std::size_t pos = 0;
    const std::string_view kw = next_token(line, pos);
    if (kw.empty()) continue;
    const std::string where = at_line(name, line_no);
    if (line.back() == '\\') throw InputError(where, "line continuation '\\' is not supported");
    if (kw == "v") {
      double c[3];
      int k = 0;
      for (std::string_view tok = next_token(line, pos); !tok.empty(); tok = next_token(line, pos), ++k) {
        const double x = parse_number(tok, where, "vertex coordinate");
        if (k < 3) c[k] = x;
      }
      if (k < 3 || k > 7) throw InputError(where, "v needs 3 coordinates (plus optional w or r g b)");
      if (m.positions.size() >= limits.max_vertices)
        throw InputError(where, "more than " + std::to_string(limits.max_vertices) + " vertices");
      m.positions.emplace_back(c[0], c[1], c[2]);
    } else if (kw == "vt") {
      double c[2] = {0.0, 0.0};
      int k = 0;
      for (std::string_view tok = next_token(line, pos); !tok.empty(); tok = next_token(line, pos), ++k) {
        const double x = parse_number(tok, where, "texture coordinate");
        if (k < 2) c[k] = x;
      }
      if (k < 1 || k > 3) throw InputError(where, "vt needs 1 to 3 numbers");
      if (m.uvs.size() >= limits.max_vertices)
        throw InputError(where, "more than " + std::to_string(limits.max_vertices) + " texture coordinates");
      m.uvs.emplace_back(c[0], c[1]);
    } else if (kw == "f") {
      fp.clear();
      ft.clear();
      int with_uv = 0;
      for (std::string_view tok = next_token(line, pos); !tok.empty(); tok = next_token(line, pos)) {
        const std::size_t s1 = tok.find('/');
        fp.push_back(resolve_index(tok.substr(0, s1), m.positions.size(), where, "vertex"));
        std::int32_t t = -1;
        if (s1 != std::string_view::npos) {
          const std::string_view rest = tok.substr(s1 + 1);
          const std::size_t s2 = rest.find('/');
          const std::string_view vt = rest.substr(0, s2);
          if (s2 != std::string_view::npos && rest.find('/', s2 + 1) != std::string_view::npos)
            throw InputError(where, "malformed face corner " + trace_text::quote(tok));
          if (!vt.empty()) {
            t = static_cast<std::int32_t>(resolve_index(vt, m.uvs.size(), where, "texture coordinate"));
            ++with_uv;
          }
          // the normal index (after the second '/') is not needed by the feedback renderer
          if (s2 != std::string_view::npos && rest.substr(s2 + 1).empty())
            throw InputError(where, "malformed face corner " + trace_text::quote(tok) + " (empty normal index)");
        }
        ft.push_back(t);
      }
      if (fp.size() < 3) throw InputError(where, "a face needs at least 3 corners");
      if (with_uv != 0 && with_uv != static_cast<int>(fp.size()))
        throw InputError(where, "face mixes corners with and without texture coordinates");
      ++st.faces;
      if (with_uv == 0) ++st.untextured_faces;
      if (m.tris.size() + (fp.size() - 2) > limits.max_triangles)
        throw InputError(where, "more than " + std::to_string(limits.max_triangles) + " triangles");
      for (std::size_t k = 1; k + 1 < fp.size(); ++k) {
        const glm::dvec3 a = m.positions[fp[0]], b = m.positions[fp[k]], c = m.positions[fp[k + 1]];
        const glm::dvec3 e1 = b - a, e2 = c - a;
        const glm::dvec3 n = glm::cross(e1, e2);
        // Zero area, or so thin (sine of the corner angle below 1e-12) that its plane is noise.
        const double n2 = glm::dot(n, n);
        if (!(n2 > 1e-24 * glm::dot(e1, e1) * glm::dot(e2, e2)) || n2 == 0.0) {
          ++st.degenerate_skipped;
          continue;
        }
        m.tris.push_back(Mesh::Tri{{fp[0], fp[k], fp[k + 1]}, {ft[0], ft[k], ft[k + 1]}});
      }
    } else {
      ++st.ignored_statements;  // vn, vp, o, g, s, usemtl, mtllib, l, p, curves, unknown
    }
  }
  st.lines = static_cast<std::uint64_t>(line_no);
  st.triangles = m.tris.size();
  if (m.tris.empty()) throw InputError(name, "no (non-degenerate) faces");
  if (stats_out) *stats_out = st;
  return m;
}

Mesh load_obj(const std::string& path, ObjStats* stats, const ObjLimits& limits) {
  const std::string text = read_regular_file(path, limits.max_bytes, "more than the limit for an OBJ file");
  return parse_obj(text, path, stats, limits);
}

std::vector<std::string> obj_warnings(const ObjStats& stats, const std::string& path) {
  std::vector<std::string> out;
  if (stats.degenerate_skipped > 0)
    out.push_back(path + ": " + std::to_string(stats.degenerate_skipped) + " of " +
                  std::to_string(stats.degenerate_skipped + stats.triangles) +
                  " triangles skipped: zero area (collinear or repeated corners)");
  return out;
}

}  // namespace vtsim
