// vtsim compare's inputs: two JSON documents (summaries or benchmark JSONs) and a tolerances TOML,
// the three parts of the input separated by 0xFF bytes, compared and reported as the CLI does.
#include <string>

#include "fuzz_targets.h"
#include "sim/compare/compare.h"

namespace vtsim::fuzz {

void compare(const std::uint8_t* data, std::size_t size) {
  // Not structured bindings: clang 14 cannot capture them in a lambda.
  const auto p1 = split2(data, size);
  const auto p2 = split2(reinterpret_cast<const std::uint8_t*>(p1.second.data()), p1.second.size());
  const std::string_view base = p1.first, now = p2.first, tol = p2.second;
  const auto file = [](std::string_view s, const char* ext) {
    return input_file(reinterpret_cast<const std::uint8_t*>(s.data()), s.size(), ext);
  };
  expect_accept_or_reject("compare", [&] {
    CompareOptions opt;
    if (!tol.empty()) opt.rules = load_tolerances(file(tol, "tol.toml"));
    const std::string bp = file(base, "base.json");
    const auto b = load_json_file(bp);
    const std::string np = now.empty() ? bp : file(now, "now.json");
    const auto n = now.empty() ? b : load_json_file(np);
    for (const bool strict : {false, true}) {
      opt.strict = strict;
      const CompareReport r = compare_documents(b, bp, n, np, opt);
      (void)format_report(r, true, strict);
      (void)report_json(r, true, strict).dump(2);
    }
  });
}

}  // namespace vtsim::fuzz
