#pragma once
// Writing tile stores: the crash-safe streaming writer every producer uses, and the builder that
// turns images (anything OpenImageIO reads; one image per layer) into a mip-mapped, bordered,
// tiled store. The procedural generator is in store_generator.h. Spec: docs/store-format.md.
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "core/atomic_file.h"
#include "core/tile_key.h"
#include "stream/store/i_codec.h"
#include "stream/store/store_format.h"

namespace vtsim {

// (Named apart from sim/run/replay_config.h's LayerSpec: two classes of one name in one namespace
// break the one-definition rule, and the linker then mixes their vector code.)
struct StoreLayerSpec {
  std::string name;                                 // <= 31 bytes
  std::uint32_t channels = 4;                       // 1..4
  CodecSpec codec;                                  // codec and its parameter
  store::Transfer transfer = store::Transfer::srgb; // how mips are filtered
};

struct StoreSpec {
  std::uint64_t width = 0, height = 0;  // level 0, texels
  std::uint32_t tile = 128;             // payload side T, texels
  std::uint32_t border = 4;             // B, texels (crazii 2017: 4 = one compressed block)
  std::uint32_t levels = 0;             // 0 = down to 1 x 1
  std::vector<StoreLayerSpec> layers;
};

// One tile after encoding: what StoreWriter::append writes.
struct EncodedTile {
  TileKey key;
  store::CodecId codec = store::CodecId::raw;  // the layer's, or raw where that did not shrink it
  std::vector<std::uint8_t> payload;
};

// Streams tile records into a temporary file beside `out_path` (same directory, so the final
// rename is atomic), and on commit() writes index and header, fsyncs the file, renames it over
// `out_path` and fsyncs the directory. Until commit() returns, `out_path` is untouched (a
// previous store there survives); if the writer is destroyed uncommitted (an exception, a
// failed build) the temporary file is removed. A process killed outright leaves at most a
// ".NAME.tmp-XXXXXX" file, never a partial `out_path`.
//
// Memory: 32 bytes per tile for the index plus one tile. encode() is const and thread-safe (many
// workers may encode at once); append(), add_tile() and commit() are single-threaded.
class StoreWriter {
 public:
  // Validates the spec (InputError naming the option: "--tile", "--border", "--levels",
  // "--layers"...), then creates the temporary file (InputError if the directory is not writable).
  StoreWriter(const std::string& out_path, const StoreSpec& spec);
  ~StoreWriter();
  StoreWriter(const StoreWriter&) = delete;
  StoreWriter& operator=(const StoreWriter&) = delete;

  const store::Geometry& geometry() const { return header_.geom; }
  const store::StoreHeader& header() const { return header_; }
  std::uint32_t tile_bytes(std::uint32_t layer) const { return header_.tile_bytes(layer); }

  // Encodes one tile of (T+2B)^2 * channels texels with its layer's codec; stores raw when the
  // codec does not make it smaller (so stored bytes <= decoded bytes always).
  EncodedTile encode(TileKey k, const std::uint8_t* texels) const;
  // Appends a record (any tile order; each tile exactly once, else InputError).
  void append(const EncodedTile& t);
  void add_tile(TileKey k, const std::uint8_t* texels) { append(encode(k, texels)); }
  // Requires every tile; writes index and header, fsync, rename, fsync the directory.
  void commit();

  std::uint64_t tiles_written() const { return tiles_written_; }
  std::uint64_t stored_bytes() const { return stored_bytes_; }    // payload bytes appended
  std::uint64_t decoded_bytes() const { return decoded_bytes_; }  // their decoded size

 private:
  void flush_buffer();

  std::string out_path_, tmp_path_;
  std::unique_ptr<AtomicFile> file_;  // the temporary the store is written to
  int fd_ = -1;                       // file_'s descriptor until commit()
  bool committed_ = false;
  store::StoreHeader header_;
  std::vector<std::unique_ptr<ICodec>> codecs_;  // per layer
  std::vector<store::IndexEntry> index_;
  std::vector<std::uint8_t> written_;            // per slot: 1 once appended
  std::uint64_t end_ = 0;                        // file offset of the next record
  std::vector<std::uint8_t> buffer_;             // records not yet written, starting at buf_start_
  std::uint64_t buf_start_ = 0;
  std::uint64_t tiles_written_ = 0, stored_bytes_ = 0, decoded_bytes_ = 0;
};

// ---- images and mips (exposed for tests and tools) ---------------------------------------------

// An 8-bit image, row-major, channels interleaved.
struct Image8 {
  std::uint64_t width = 0, height = 0;  // texels
  std::uint32_t channels = 0;
  std::vector<std::uint8_t> texels;     // width * height * channels
  const std::uint8_t* at(std::uint64_t x, std::uint64_t y) const { return &texels[(y * width + x) * channels]; }
};

// Reads any image OpenImageIO reads (first subimage, first 4 channels) as 8 bits per channel.
// 8-bit sources are taken as they are; float and half sources (linear light) are encoded with the
// sRGB curve when `transfer` is srgb, else clamped to [0, 1]; 16-bit sources are rescaled.
// Throws InputError naming the file, also before allocating anything when the image needs more than
// max_bytes to read (its 8-bit texels, one ~16 MiB chunk of rows, OpenImageIO's own buffer:
// image_io::require_read_memory): a header alone can claim 2^31 × 2^31 pixels. The texels grow
// with the rows read, so a file holding fewer rows than its header claims fails early. A file the
// reader reports damaged while giving pixels anyway (libjpeg and libtiff fill what they cannot
// decode: a truncated JPEG's missing rows come back grey) throws at the first damaged chunk of
// rows, unless accept_damaged: then the filled image is returned.
Image8 read_image8(const std::string& path, store::Transfer transfer,
                   std::uint64_t max_bytes = std::numeric_limits<std::uint64_t>::max(), bool accept_damaged = false);

// Writes an 8-bit image with OpenImageIO (format from the extension). Throws InputError.
void write_image8(const std::string& path, const Image8& image);

// Levels 0..levels-1 of an image under ceil halving (level 0 is `level0` itself). Each texel of
// level l+1 is the area-weighted mean of the (up to 2 x 2) level-l texels it covers, weighted by
// how many level-0 texels each covers, i.e. the exact mean of its level-0 footprint
// [i*2^l, min((i+1)*2^l, W)) x (same in y). sRGB colour channels are averaged in linear light;
// linear layers and alpha as stored. Intermediate levels stay in float; each is rounded once.
std::vector<Image8> build_mip_chain(const Image8& level0, store::Transfer transfer, std::uint32_t levels);

// The stored texels of tile (tx, ty) of a level image: stored texel (i, j), 0 <= i, j < T + 2B,
// is level texel (clamp(tx*T - B + i, 0, W_l - 1), clamp(ty*T - B + j, 0, H_l - 1)): true
// neighbours inside the texture, clamp-to-edge outside it (borders and partial-tile padding).
void extract_tile(const Image8& level, std::uint32_t tile, std::uint32_t border, std::uint64_t tx,
                  std::uint64_t ty, std::uint8_t* out);

// ---- building a store from images --------------------------------------------------------------

// Called with the fraction done in [0, 1]; may throw to abort (the build then leaves no output).
using ProgressFn = std::function<void(double fraction)>;

struct BuildOptions {
  std::uint32_t tile = 128, border = 4, levels = 0;  // levels 0 = down to 1 x 1
  std::vector<std::string> layer_names;              // empty: the image file stems
  std::vector<CodecSpec> codecs;                     // one for all layers, or one per layer
  std::vector<store::Transfer> transfers;            // empty: srgb; one for all, or one per layer
  unsigned threads = 0;                              // encode workers; 0 = hardware threads
  std::uint64_t memory_limit_bytes = 0;              // the level-0 images together, each with its
                                                     // read buffers (read_image8's max_bytes is
                                                     // what earlier layers left), and the mip
                                                     // walk's peak (checked from the headers
                                                     // first); 0 = usable_memory_bytes()
  bool accept_damaged = false;                       // build from images the reader reports
                                                     // damaged, its filler included (read_image8)
};

struct BuildResult {
  std::uint64_t tiles = 0, stored_bytes = 0, decoded_bytes = 0, file_bytes = 0;
};

// One image per layer, all the same size. Throws InputError for bad images or options.
BuildResult build_store(const std::vector<std::string>& images, const BuildOptions& options,
                        const std::string& out_path, const ProgressFn& progress = {});

// Encodes tiles on `threads` workers and appends them in a fixed order, so the file is the same
// for any thread count. produce(i, out) fills the EncodedTiles of work item i (called on a worker);
// items are appended in order 0..count-1. Used by the builder and the generator.
void encode_in_order(StoreWriter& writer, std::uint64_t count, unsigned threads,
                     const std::function<void(std::uint64_t, std::vector<EncodedTile>&)>& produce,
                     const ProgressFn& progress);

}  // namespace vtsim
