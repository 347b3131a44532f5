// vtsim store …: build, generate, inspect and verify tile stores (docs/store-format.md).
#include <fmt/core.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstring>
#include <cstdio>
#include <optional>
#include <nlohmann/json.hpp>
#include <system_error>

#include "cli/cli_io.h"
#include "cli/commands.h"
#include "cli/format.h"
#include "core/error.h"
#include "stream/store/store_builder.h"
#include "stream/store/store_generator.h"
#include "stream/store/tile_store.h"
#include "sim/run/replay_config.h"
#include "sim/run/systems.h"

namespace vtsim::cli {
namespace {

std::vector<std::string> split_commas(const std::string& s) {
  std::vector<std::string> out;
  std::size_t pos = 0;
  while (pos <= s.size()) {
    const std::size_t c = std::min(s.find(',', pos), s.size());
    out.push_back(s.substr(pos, c - pos));
    pos = c + 1;
  }
  return out;
}

// "WxH" -> width, height. Throws InputError naming the option.
void parse_store_size(const std::string& s, std::uint64_t& w, std::uint64_t& h) {
  const std::size_t x = s.find_first_of("xX");
  try {
    std::size_t a = 0, b = 0;
    if (x == std::string::npos) throw std::invalid_argument("no x");
    w = std::stoull(s.substr(0, x), &a);
    h = std::stoull(s.substr(x + 1), &b);
    if (a != x || b != s.size() - x - 1 || s[0] == '-' || s[x + 1] == '-') throw std::invalid_argument("junk");
  } catch (const std::exception&) {
    throw InputError("--size", "'" + s + "' is not WIDTHxHEIGHT in texels (e.g. 16384x8192)");
  }
}

// Percentage on stderr when stderr is a terminal (rewritten in place) or --progress was given (a
// line each 10 %, no "\r" in a log).
ProgressFn progress_printer(const char* what, bool forced) {
  const bool tty = stderr_is_terminal();
  if (!forced && !tty) return {};
  return [what, tty, last = -1](double f) mutable {
    const int pct = static_cast<int>(f * 100.0);
    if (pct == last || (!tty && pct / 10 == last / 10 && pct < 100)) return;
    last = pct;
    if (tty) fmt::print(stderr, "\r{}: {:3d}%{}", what, pct, pct >= 100 ? "\n" : "");
    else fmt::print(stderr, "{}: {:3d}%\n", what, pct);
    std::fflush(stderr);
  };
}

// Ctrl-C / SIGTERM during build or gen: the next progress tick throws, the writer removes its
// temporary file, and the output is left as it was (exit 130, the shell's code for SIGINT).
volatile std::sig_atomic_t g_interrupted = 0;
extern "C" void on_interrupt(int) { g_interrupted = 1; }
struct Interrupted {};

class InterruptGuard {
 public:
  InterruptGuard() {
    g_interrupted = 0;
    old_int_ = std::signal(SIGINT, on_interrupt);
    old_term_ = std::signal(SIGTERM, on_interrupt);
  }
  ~InterruptGuard() {
    std::signal(SIGINT, old_int_);
    std::signal(SIGTERM, old_term_);
  }
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;

 private:
  void (*old_int_)(int) = SIG_DFL;
  void (*old_term_)(int) = SIG_DFL;
};

ProgressFn interruptible(ProgressFn inner) {
  return [inner = std::move(inner)](double f) {
    if (g_interrupted) throw Interrupted{};
    if (inner) inner(f);
  };
}

template <class F>
void run_interruptible(const std::string& out, F&& f) {
  InterruptGuard guard;
  try {
    f();
  } catch (const Interrupted&) {
    fmt::print(stderr, "\nvtsim: interrupted; {} was not written\n", out);
    throw Exit{130};
  }
}

void print_result(const std::string& out, const BuildResult& r, bool json = false) {
  if (json) {
    fmt::print("{}\n", nlohmann::json{{"path", out}, {"tiles", r.tiles}, {"file_bytes", r.file_bytes},
                                      {"stored_bytes", r.stored_bytes}, {"decoded_bytes", r.decoded_bytes}}
                           .dump(2));
    return;
  }
  fmt::print("wrote {}: {} tiles, {} ({} payload for {} decoded, ratio {:.2f})\n", out, r.tiles,
             human_bytes(static_cast<double>(r.file_bytes)), human_bytes(static_cast<double>(r.stored_bytes)),
             human_bytes(static_cast<double>(r.decoded_bytes)),
             r.stored_bytes ? static_cast<double>(r.decoded_bytes) / static_cast<double>(r.stored_bytes) : 0.0);
}

nlohmann::json info_json(const TileStore& s) {
  const auto& h = s.header();
  const auto& g = h.geom;
  nlohmann::json j;
  j["path"] = s.path();
  j["version"] = fmt::format("{}.{}", h.version_major, h.version_minor);
  j["width"] = g.width;
  j["height"] = g.height;
  j["tile"] = g.tile;
  j["border"] = g.border;
  j["stored_side"] = g.stored_side();
  j["file_bytes"] = h.file_bytes;
  j["index_bytes"] = h.index_bytes;
  j["tiles"] = g.tile_count();
  nlohmann::json levels = nlohmann::json::array();
  for (std::uint32_t l = 0; l < g.levels; ++l)
    levels.push_back({{"level", l}, {"width", g.level_width(l)}, {"height", g.level_height(l)}, {"tiles_x", g.cols[l]}, {"tiles_y", g.rows[l]}});
  j["levels"] = levels;
  const auto totals = s.totals();
  nlohmann::json layers = nlohmann::json::array();
  std::uint64_t stored = 0, decoded = 0, read = 0;
  for (std::uint32_t i = 0; i < g.layers; ++i) {
    const auto& L = h.layers[i];
    const auto& t = totals[i];
    layers.push_back({{"name", L.name},
                      {"channels", L.channels},
                      {"bits", L.bits},
                      {"codec", std::string(codec_name(L.codec))},
                      {"codec_param", L.codec_param},
                      {"transfer", L.transfer == store::Transfer::srgb ? "srgb" : "linear"},
                      {"tile_bytes", h.tile_bytes(i)},
                      {"stored_bytes", t.stored_bytes},
                      {"read_bytes", t.read_bytes},
                      {"decoded_bytes", t.decoded_bytes},
                      {"compression_ratio", static_cast<double>(t.decoded_bytes) / static_cast<double>(t.stored_bytes)},
                      {"mean_stored_bytes_per_tile", static_cast<double>(t.stored_bytes) / static_cast<double>(t.tiles)}});
    stored += t.stored_bytes;
    decoded += t.decoded_bytes;
    read += t.read_bytes;
  }
  j["layers"] = layers;
  j["stored_bytes"] = stored;
  j["read_bytes"] = read;
  j["decoded_bytes"] = decoded;
  j["compression_ratio"] = static_cast<double>(decoded) / static_cast<double>(stored);
  j["alignment_overhead"] = static_cast<double>(read) / static_cast<double>(stored);
  return j;
}

void print_info(const TileStore& s) {
  const nlohmann::json j = info_json(s);
  fmt::print("{}: vtsim tile store v{}\n", s.path(), j["version"].get<std::string>());
  fmt::print("  texture  {} x {} texels, {} levels, tile {} + border {} (stored {} x {})\n", j["width"].get<std::uint64_t>(),
             j["height"].get<std::uint64_t>(), j["levels"].size(), j["tile"].get<std::uint32_t>(), j["border"].get<std::uint32_t>(),
             j["stored_side"].get<std::uint32_t>(), j["stored_side"].get<std::uint32_t>());
  fmt::print("  file     {} ({} bytes), {} tiles, index {}\n", human_bytes(j["file_bytes"].get<double>()),
             j["file_bytes"].get<std::uint64_t>(), j["tiles"].get<std::uint64_t>(),
             human_bytes(j["index_bytes"].get<double>()));
  fmt::print("  levels  ");
  for (const auto& l : j["levels"])
    fmt::print(" {}:{}x{}", l["level"].get<int>(), l["width"].get<std::uint64_t>(), l["height"].get<std::uint64_t>());
  fmt::print("\n");
  for (const auto& L : j["layers"])
    fmt::print("  layer {:<10} {}ch {} {}:{:<3} stored {:>10} for {:>10} decoded, ratio {:6.2f}, {:.0f} B/tile\n",
               L["name"].get<std::string>(), L["channels"].get<int>(), L["transfer"].get<std::string>(), L["codec"].get<std::string>(),
               L["codec_param"].get<int>(), human_bytes(L["stored_bytes"].get<double>()),
               human_bytes(L["decoded_bytes"].get<double>()), L["compression_ratio"].get<double>(),
               L["mean_stored_bytes_per_tile"].get<double>());
  fmt::print("  total    stored {} for {} decoded, ratio {:.2f}; 4 KiB-aligned reads {} (x{:.3f})\n",
             human_bytes(j["stored_bytes"].get<double>()), human_bytes(j["decoded_bytes"].get<double>()),
             j["compression_ratio"].get<double>(), human_bytes(j["read_bytes"].get<double>()),
             j["alignment_overhead"].get<double>());
}

// Reads every record in file order (O_DIRECT when the filesystem allows), checks each checksum
// and decode. Returns the number of bad tiles.
std::uint64_t verify(const TileStore& s, bool want_direct, std::uint64_t max_report, const ProgressFn& progress,
                     nlohmann::json* bad_json = nullptr) {
  DirectOpen f = open_for_read(s.path(), want_direct);
  if (!f.warning.empty()) warn(f.warning);
  const auto& g = s.geometry();
  std::vector<std::uint64_t> order(s.index().size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](auto a, auto b) { return s.index()[a].offset < s.index()[b].offset; });
  AlignedBuffer rec, out;
  std::uint64_t bad = 0;
  for (std::size_t n = 0; n < order.size(); ++n) {
    const TileKey k = g.key_of_slot(order[n]);
    const TileLocation loc = s.locate(k);
    rec.reserve(loc.read_bytes);
    out.reserve(loc.decoded_bytes);
    try {
      std::size_t got = 0;
      try {
        got = f.file.pread_full(rec.data(), loc.read_bytes, loc.offset);
      } catch (const std::system_error& e) {
        throw InputError(s.path() + ": " + store::describe(k), e.what());
      }
      if (got < loc.stored_bytes) throw InputError(s.path() + ": " + store::describe(k), "short read");
      s.verify_and_decode(k, rec.data(), got, out.data(), out.size());
    } catch (const InputError& e) {
      if (bad < max_report) {
        if (bad_json) bad_json->push_back({{"layer", k.layer()}, {"level", k.level()}, {"x", k.x()}, {"y", k.y()}, {"reason", e.what()}});
        else fmt::print("BAD {}\n", e.what());
      }
      ++bad;
    }
    if (progress && (n % 256 == 0 || n + 1 == order.size())) progress(static_cast<double>(n + 1) / static_cast<double>(order.size()));
  }
  return bad;
}

// One level of one layer as an image, assembled from the tiles' interiors.
Image8 extract_level(const TileStore& s, std::uint32_t layer, std::uint32_t level) {
  if (layer >= s.layer_count()) throw InputError("--layer", fmt::format("{} is out of range 0..{}", layer, s.layer_count() - 1));
  if (level >= s.level_count()) throw InputError("--level", fmt::format("{} is out of range 0..{}", level, s.level_count() - 1));
  const auto& g = s.geometry();
  Image8 img;
  img.width = g.level_width(level);
  img.height = g.level_height(level);
  img.channels = s.layer(layer).channels;
  if (img.width * img.height > (std::uint64_t{1} << 28))
    throw InputError("--level", fmt::format("level {} is {}x{} texels; extract a coarser level (at most 2^28 texels)", level,
                                            img.width, img.height));
  img.texels.resize(img.width * img.height * img.channels);
  AlignedBuffer scratch;
  std::vector<std::uint8_t> t(s.tile_bytes(layer));
  const std::uint64_t c = img.channels, S = g.stored_side();
  for (std::uint64_t ty = 0; ty < g.rows[level]; ++ty)
    for (std::uint64_t tx = 0; tx < g.cols[level]; ++tx) {
      s.read_tile(TileKey(layer, level, static_cast<std::int64_t>(tx), static_cast<std::int64_t>(ty)), scratch, t.data(), t.size());
      for (std::uint64_t j = 0; j < g.tile && ty * g.tile + j < img.height; ++j) {
        const std::uint64_t n = std::min<std::uint64_t>(g.tile, img.width - tx * g.tile);
        std::memcpy(&img.texels[((ty * g.tile + j) * img.width + tx * g.tile) * c], &t[((j + g.border) * S + g.border) * c], n * c);
      }
    }
  return img;
}

// A store every replay would refuse is refused before it is written (a 228 MiB store of 7-texel
// tiles was): the tile side, border and size go through the replay config's own checks
// (texture.tile_size >= 8, ...), and --levels must hold the levels at least one streaming system
// samples (a warning names the systems that need more). width = 0: the size is not known yet
// (store build reads it from the image). Throws InputError naming the flag.
void check_store_replayable(std::uint64_t width, std::uint64_t height, std::uint32_t tile, std::uint32_t border,
                            std::uint32_t levels) {
  std::vector<std::string> sets = {fmt::format("texture.tile_size={}", tile), fmt::format("texture.border={}", border)};
  if (width > 0) {
    sets.push_back(fmt::format("texture.width={}", width));
    sets.push_back(fmt::format("texture.height={}", height));
  }
  // Accepted when at least one streaming system accepts it (the clipmap wants border 0, a virtual
  // texture a border: a store is made for one of them).
  std::optional<ReplayConfig> accepted;
  std::string refused;
  for (const SystemInfo& sys : streaming_systems().entries()) {
    std::vector<std::string> with = sets;
    with.push_back("run.system=" + std::string(sys.name));
    try {
      accepted = load_replay_config("", with);
      break;
    } catch (const InputError& e) {
      if (!refused.empty()) continue;  // the first system's reason
      const std::string m = e.what();
      const char* flag = m.find("texture.tile_size") != std::string::npos ? "--tile"
                         : m.find("texture.border") != std::string::npos ? "--border"
                                                                           : "--size";
      const std::size_t colon = m.find("': ");
      refused = std::string(flag) + "\n" + (colon == std::string::npos ? m : m.substr(colon + 3));
    }
  }
  if (!accepted) {
    const std::size_t nl = refused.find('\n');
    throw InputError(refused.substr(0, nl), refused.substr(nl + 1) + " (no replay could read this store)");
  }
  const ReplayConfig& cfg = *accepted;
  if (levels == 0 || width == 0) return;
  std::string need_more;
  int fewest = 1 << 30;
  for (const SystemInfo& sys : streaming_systems().entries()) {
    ReplayConfig c = cfg;
    c.run.system = std::string(sys.name);
    const int need = sys.store_levels(c);  // the levels' count depends on the texture, not on the border
    fewest = std::min(fewest, need);
    if (static_cast<int>(levels) < need)
      need_more += fmt::format("{}{} needs {} ({})", need_more.empty() ? "" : "; ", sys.name, need, sys.store_levels_why);
  }
  if (static_cast<int>(levels) < fewest)
    throw InputError("--levels", fmt::format("{} levels is fewer than any streaming system samples: {}; leave --levels unset "
                                             "(down to 1x1)",
                                             levels, need_more));
  if (!need_more.empty()) warn(fmt::format("--levels {}: some systems will refuse this store: {}", levels, need_more));
}

// vtsim store build's options as typed.
struct StoreBuildArgs {
  std::vector<std::string> images;
  std::string out, codecs = "zstd", names, transfers = "srgb";
  std::uint32_t tile = 128, border = 4, levels = 0;
  unsigned threads = 0;
  bool progress = false, accept_damaged = false, json = false;
};

// The builder's options from the typed ones; throws InputError naming the option (--codec first,
// then --transfer).
BuildOptions store_build_options(const StoreBuildArgs& a) {
  BuildOptions b;
  b.accept_damaged = a.accept_damaged;
  b.tile = a.tile;
  b.border = a.border;
  b.levels = a.levels;
  b.threads = a.threads;
  for (const auto& s : split_commas(a.codecs)) b.codecs.push_back(parse_codec_spec(s, "--codec"));
  if (!a.names.empty()) b.layer_names = split_commas(a.names);
  for (const auto& s : split_commas(a.transfers)) {
    if (s == "srgb") b.transfers.push_back(store::Transfer::srgb);
    else if (s == "linear") b.transfers.push_back(store::Transfer::linear);
    else throw InputError("--transfer", "'" + s + "' is not srgb or linear");
  }
  return b;
}

void register_store_build(CLI::App* store) {
  auto* c = store->add_subcommand("build", "Build a tile store from images (one image per layer)");
  auto o = std::make_shared<StoreBuildArgs>();
  c->add_option("IMAGE", o->images, "Images OpenImageIO reads (PNG, JPEG, TIFF, EXR...), one per layer")->required();
  c->add_option("-o,--output", o->out, "Output store (.vts)")->required();
  c->add_option("--tile", o->tile, "Payload tile side T in texels")->capture_default_str();
  c->add_option("--border", o->border, "Border B in texels on each side (stored side T+2B)")->capture_default_str();
  c->add_option("--levels", o->levels, "Number of levels (0 = down to 1x1)")->capture_default_str();
  std::string specs;  // "raw, zstd[:1-22], ...": from the codec table
  for (const CodecInfo& e : codecs().entries()) specs += (specs.empty() ? "" : ", ") + std::string(e.spec);
  c->add_option("--codec", o->codecs, "Codec per layer, comma-separated: " + specs)
      ->capture_default_str();
  c->add_option("--layer-names", o->names, "Layer names, comma-separated (default: image file names)");
  c->add_option("--transfer", o->transfers, "srgb or linear per layer (mip filtering in linear light for srgb)")->capture_default_str();
  c->add_option("--threads", o->threads, "Encode threads (0 = all cores); the file does not depend on it");
  c->add_flag("--progress", o->progress, "Show progress even when stderr is not a terminal");
  c->add_flag("--json", o->json, "Print the result (tiles, bytes) as JSON");
  c->add_flag("--accept-damaged", o->accept_damaged,
              "Build from images the reader reports damaged (truncated JPEG/TIFF), its filler included");
  c->callback([o] {
    const BuildOptions b = store_build_options(*o);
    check_store_replayable(0, 0, o->tile, o->border, o->levels);
    check_output("--output", o->out);
    run_interruptible(o->out, [&] {
      const BuildResult r = build_store(o->images, b, o->out, interruptible(progress_printer("store build", o->progress)));
      print_result(o->out, r, o->json);
    });
  });
}

// vtsim store gen's options as typed.
struct StoreGenArgs {
  std::string out, size, layers = "albedo:zstd,normal:lz4";
  std::uint32_t tile = 128, border = 4, levels = 0;
  std::uint64_t seed = 1;
  double feature = 4096;  // level-0 texels
  unsigned threads = 0;
  bool progress = false, json = false;
};

// The generator's options from the typed ones; throws InputError naming the option (--size
// first, then --layers).
GenOptions store_gen_options(const StoreGenArgs& a) {
  GenOptions g;
  parse_store_size(a.size, g.width, g.height);
  g.tile = a.tile;
  g.border = a.border;
  g.levels = a.levels;
  g.seed = a.seed;
  g.feature_texels = a.feature;
  g.threads = a.threads;
  g.layers = parse_gen_layers(a.layers, "--layers");
  return g;
}

void register_store_gen(CLI::App* store) {
  auto* c = store->add_subcommand("gen", "Generate a procedural terrain store of any size (deterministic)");
  auto o = std::make_shared<StoreGenArgs>();
  c->add_option("-o,--output", o->out, "Output store (.vts)")->required();
  c->add_option("--size", o->size, "Level-0 size WIDTHxHEIGHT in texels")->required();
  c->add_option("--tile", o->tile, "Payload tile side T in texels")->capture_default_str();
  c->add_option("--border", o->border, "Border B in texels")->capture_default_str();
  c->add_option("--levels", o->levels, "Number of levels (0 = down to 1x1)")->capture_default_str();
  c->add_option("--layers", o->layers, "Layers name:codec[:param], comma-separated; names albedo*, normal*, height*")
      ->capture_default_str();
  c->add_option("--seed", o->seed, "Noise seed")->capture_default_str();
  c->add_option("--feature", o->feature, "Wavelength of the largest terrain features, level-0 texels")->capture_default_str();
  c->add_option("--threads", o->threads, "Worker threads (0 = all cores); the file does not depend on it");
  c->add_flag("--progress", o->progress, "Show progress even when stderr is not a terminal");
  c->add_flag("--json", o->json, "Print the result (tiles, bytes) as JSON");
  c->callback([o] {
    const GenOptions g = store_gen_options(*o);
    check_store_replayable(g.width, g.height, o->tile, o->border, o->levels);
    check_output("--output", o->out);
    run_interruptible(o->out, [&] {
      const BuildResult r = generate_store(g, o->out, interruptible(progress_printer("store gen", o->progress)));
      print_result(o->out, r, o->json);
    });
  });
}

void register_store_info(CLI::App* store) {
  auto* c = store->add_subcommand("info", "Sizes, levels, layers, codecs and compression of a store");
  auto path = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  c->add_option("STORE", *path, "Tile store (.vts)")->required();
  c->add_flag("--json", *json, "Print JSON");
  c->callback([path, json] {
    const TileStore s = TileStore::open(*path);
    for (const std::string& w : s.header().warnings) warn(w);
    if (*json) fmt::print("{}\n", info_json(s).dump(2));
    else print_info(s);
  });
}

void register_store_extract(CLI::App* store) {
  auto* c = store->add_subcommand("extract", "Write one level of one layer as an image (assembled from the tiles)");
  struct Opts {
    std::string path, out;
    std::uint32_t layer = 0, level = 0;
  };
  auto o = std::make_shared<Opts>();
  c->add_option("STORE", o->path, "Tile store (.vts)")->required();
  c->add_option("-o,--output", o->out, "Image to write (PNG, TIFF, ... by extension)")->required();
  c->add_option("--layer", o->layer, "Layer index")->capture_default_str();
  c->add_option("--level", o->level, "Mip level")->capture_default_str();
  c->callback([o] {
    check_output("--output", o->out);  // before the work
    const TileStore s = TileStore::open(o->path);
    for (const std::string& w : s.header().warnings) warn(w);
    const Image8 img = extract_level(s, o->layer, o->level);
    write_image8(o->out, img);
    fmt::print("wrote {}: layer {} ('{}') level {}, {}x{}x{}\n", o->out, o->layer, s.layer(o->layer).name, o->level, img.width,
               img.height, img.channels);
  });
}

void register_store_verify(CLI::App* store) {
  auto* c = store->add_subcommand("verify", "Check every tile's checksum and that it decodes; list bad tiles (exit 1 if any)");
  struct Opts {
    std::string path;
    bool buffered = false, progress = false, json = false;
    std::uint64_t max_report = 100;
  };
  auto o = std::make_shared<Opts>();
  c->add_option("STORE", o->path, "Tile store (.vts)")->required();
  c->add_flag("--buffered", o->buffered, "Read through the page cache instead of O_DIRECT");
  c->add_option("--max-report", o->max_report, "List at most this many bad tiles")->capture_default_str();
  c->add_flag("--progress", o->progress, "Show progress even when stderr is not a terminal");
  c->add_flag("--json", o->json, "Print the result (tiles, bad tiles with their reasons) as JSON");
  c->callback([o] {
    const TileStore s = TileStore::open(o->path);
    for (const std::string& w : s.header().warnings) warn(w);
    nlohmann::json bad_tiles = nlohmann::json::array();
    const std::uint64_t bad = verify(s, !o->buffered, o->max_report, progress_printer("store verify", o->progress),
                                     o->json ? &bad_tiles : nullptr);
    const std::uint64_t n = s.index().size();
    if (o->json) {
      fmt::print("{}\n", nlohmann::json{{"path", o->path}, {"tiles", n}, {"bad", bad}, {"bad_tiles", bad_tiles}}.dump(2));
      if (bad) throw Exit{kExitFailure};
      return;
    }
    if (bad) {
      fmt::print("{}: {} of {} tiles are bad\n", o->path, bad, n);
      throw Exit{kExitFailure};
    }
    fmt::print("{}: all {} tiles verified (checksum and decode)\n", o->path, n);
  });
}

}  // namespace

void register_store_commands(CLI::App& app) {
  auto* store = app.add_subcommand("store", "Build, generate, inspect and verify on-disk tile stores (.vts)");
  store->require_subcommand(1);
  register_store_build(store);
  register_store_gen(store);
  register_store_info(store);
  register_store_extract(store);
  register_store_verify(store);
}

}  // namespace vtsim::cli
