#pragma once
// An engine's side of the streaming runtime in tests (stream/runtime/streaming_runtime.h): a fake
// GPU that keeps the physical page pool (VT) or the clip stack's slots (clipmap) as host memory,
// the page table and windows the runtime's updates describe, and an upload that can be told to
// throw.
#include <doctest/doctest.h>

#include <algorithm>
#include <cstring>
#include <map>
#include <stdexcept>
#include <vector>

#include "stream/runtime/streaming_runtime.h"

namespace vtsim::test {

class FakeGpu final : public IUploadSink {
 public:
  // `slot_bytes`: host bytes of one pool slot per layer (0: the simulated clock, no texels).
  FakeGpu(int layers, std::size_t slots, std::size_t slot_bytes)
      : layers_(layers), slot_bytes_(slot_bytes), pool_(slots * static_cast<std::size_t>(layers) * slot_bytes) {}

  void upload(const TileUpload& u) override {
    if (throw_next_ > 0) {
      --throw_next_;
      ++thrown_;
      thrown_key_ = u.key;
      thrown_at_ = uploaded.size();
      throw std::runtime_error("the GPU copy failed");
    }
    ++uploads;
    uploaded.push_back(u.key);
    if (u.slot >= 0 && u.data && slot_bytes_ > 0) {
      REQUIRE(u.data->bytes <= slot_bytes_);
      const std::size_t at = (static_cast<std::size_t>(u.slot) * static_cast<std::size_t>(layers_) + u.key.layer()) * slot_bytes_;
      REQUIRE(at + u.data->bytes <= pool_.size());
      std::memcpy(pool_.data() + at, u.data->texels.get(), u.data->bytes);
    }
  }
  // What the engine does after end_frame: mirror the page table and the windows.
  void apply(const FrameUpdates& f) {
    for (const PageTableUpdate& p : f.page_table) {
      if (p.slot < 0) page_table.erase(p.page);
      else page_table[p.page] = p.slot;
    }
    for (const FrameUpdates::Window& w : f.windows) windows[w.level] = w.window;
    clamp = f.clamp;
  }
  // The texels of layer `layer` in pool slot `slot`.
  const std::uint8_t* slot_texels(std::int64_t slot, std::uint32_t layer) const {
    return pool_.data() + (static_cast<std::size_t>(slot) * static_cast<std::size_t>(layers_) + layer) * slot_bytes_;
  }
  void throw_next(int n) { throw_next_ = n; }
  int thrown() const { return thrown_; }
  TileKey thrown_key() const { return thrown_key_; }      // the last tile whose upload threw
  std::size_t thrown_at_upload() const { return thrown_at_; }  // uploads made before it

  std::uint64_t uploads = 0;
  std::vector<TileKey> uploaded;
  std::map<TileKey, std::int64_t> page_table;  // page -> slot
  std::map<int, ClipWindow> windows;           // level -> window
  int clamp = 0;

 private:
  int layers_ = 1;
  std::size_t slot_bytes_ = 0;
  std::vector<std::uint8_t> pool_;
  int throw_next_ = 0;
  int thrown_ = 0;
  TileKey thrown_key_;
  std::size_t thrown_at_ = 0;
};

}  // namespace vtsim::test
