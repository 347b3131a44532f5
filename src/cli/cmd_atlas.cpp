// vtsim atlas build: brush images packed into a texture atlas (crazii 2017, stream/produce/atlas.h),
// each kept level written as an image plus a JSON manifest (docs/produced.md, "vtsim atlas build").
#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli/cli_io.h"
#include "cli/commands.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "stream/produce/atlas.h"
#include "stream/produce/brush_images.h"
#include "stream/store/store_builder.h"

namespace vtsim::cli {

namespace {

struct AtlasBuildArgs {
  std::vector<std::string> brushes;  // files, or patterns with * ? [ in the file name
  std::string out_dir;
  produce::AtlasParams params;
  std::string ext = "png";
  bool quiet = false;
};

void run_atlas_build(const AtlasBuildArgs& a) {
  namespace fs = std::filesystem;
  if (a.ext != "png" && a.ext != "tif")
    throw InputError("--format", fmt::format("'{}': give png or tif", a.ext));
  check_output_dir("--out", a.out_dir);  // before the work
  const std::vector<std::string> files = produce::expand_brush_files(a.brushes);
  if (files.empty()) throw InputError("brushes", "no brush image given");
  std::vector<produce::Rgba8> brushes;
  for (const std::string& f : files) {
    check_input("brushes", f);
    brushes.push_back(produce::read_brush(f));
  }
  const produce::Atlas at = produce::build_atlas(brushes, files, a.params);
  make_output_dir("--out", a.out_dir);  // only once the brushes made an atlas; the last level only
  nlohmann::json man;
  man["format"] = "vtsim-atlas/1";
  man["cols"] = at.cols;
  man["rows"] = at.rows;
  man["brushes"] = at.brushes;
  man["side"] = at.side;
  man["border"] = at.border;
  man["transition"] = at.transition;
  man["constant_border"] = at.constant_border;
  man["levels_kept"] = at.levels.size();
  nlohmann::json cells = nlohmann::json::array();
  for (int b = 0; b < at.brushes; ++b) {
    const produce::AtlasLevel& l0 = at.levels[0];
    cells.push_back({{"index", b}, {"file", files[static_cast<std::size_t>(b)]}, {"col", b % at.cols}, {"row", b / at.cols},
                     {"x", (b % at.cols) * l0.cell + l0.border}, {"y", (b / at.cols) * l0.cell + l0.border}});
  }
  man["cells"] = cells;
  nlohmann::json levels = nlohmann::json::array();
  for (std::size_t m = 0; m < at.levels.size(); ++m) {
    const produce::AtlasLevel& lv = at.levels[m];
    const std::string name = fmt::format("atlas_level{}.{}", m, a.ext);
    Image8 im;
    im.width = static_cast<std::uint64_t>(lv.width);
    im.height = static_cast<std::uint64_t>(lv.height);
    im.channels = 4;
    im.texels = lv.rgba;
    write_image8((fs::path(a.out_dir) / name).string(), im);
    levels.push_back({{"level", m}, {"file", name}, {"width", lv.width}, {"height", lv.height}, {"brush_side", lv.brush_side},
                      {"border", lv.border}, {"cell", lv.cell}});
  }
  man["levels"] = levels;
  write_output((fs::path(a.out_dir) / "atlas.json").string(), man.dump(2) + "\n");
  if (!a.quiet)
    fmt::print("atlas: {} brushes of {}² in {} x {} cells, border {}, {} level{} kept ({}² to {}²) -> {}/atlas.json\n", at.brushes, at.side,
               at.cols, at.rows, at.border, at.levels.size(), at.levels.size() == 1 ? "" : "s", at.levels.front().width,
               at.levels.back().width, a.out_dir);
}

}  // namespace

void register_atlas_commands(CLI::App& app) {
  auto* atlas = app.add_subcommand("atlas", "Texture atlases of brushes for produced tiles (docs/produced.md)");
  atlas->require_subcommand(1);
  auto a = std::make_shared<AtlasBuildArgs>();
  auto* b = atlas->add_subcommand("build", "Pack brush images into an atlas; write each kept level as an image and atlas.json");
  b->add_option("brushes", a->brushes, "brush images (any format OpenImageIO reads), or patterns such as 'brushes/*.png'")->required();
  b->add_option("--out,-o", a->out_dir, "output directory (created): atlas_level<m>.<format> and atlas.json")->required();
  b->add_option("--cols", a->params.cols, "cells per row")->capture_default_str();
  b->add_option("--rows", a->params.rows, "cell rows (0: as many as the brushes need)")->capture_default_str();
  b->add_option("--border", a->params.border, "texels of wrapped border around each cell at level 0 (4 = one BC block)")->capture_default_str();
  b->add_option("--transition", a->params.transition, "texels cross-faded at each brush edge (crazii 2017 item 7; 0 = none)")->capture_default_str();
  b->add_flag("--constant-border", a->params.constant_border, "keep the border at every level (each level its own texture), covering all levels");
  b->add_option("--max-side", a->params.max_side, "largest atlas side allowed, texels")->capture_default_str();
  b->add_option("--format", a->ext, "image format of the levels: png or tif (8 bits a channel)")->capture_default_str();
  b->add_flag("--quiet,-q", a->quiet, "print nothing on success");
  b->callback([a] { run_atlas_build(*a); });
}

}  // namespace vtsim::cli
