#pragma once
// A self-contained SVG chart of miss-ratio curves (cache/policy/mrc.h): miss ratio against cache
// size, sizes in MiB for byte curves and in pages for page curves, each curve's knee marked and
// labelled. No scripts, no stylesheet: it opens alone or inline in an HTML report.
#include <string>
#include <vector>

#include "cache/policy/mrc.h"

namespace vtsim {

struct MrcChartSeries {
  std::string label;  // legend text ("exact", "SHARDS 1%", a config name...)
  MissRatioCurve curve;
};

// One chart of every series (all of one unit, else std::invalid_argument; none: an empty chart
// that says so). Text is escaped; the output starts with "<svg" and ends with "</svg>\n".
std::string mrc_chart_svg(const std::vector<MrcChartSeries>& series, const std::string& title);

}  // namespace vtsim
