#pragma once
// Brush images from files: the inputs of `vtsim atlas build` and of the terrain's real-clock
// compositor (terrain.brush_files; docs/produced.md). Any format OpenImageIO reads, as 8-bit RGBA.
#include <string>
#include <vector>

#include "stream/produce/atlas.h"

namespace vtsim::produce {

// Files named by `specs`: each a file, or a pattern with * ? [ in its file name (the directory part
// taken literally) expanding to the matching files, sorted; a spec that exists as a file is taken as
// it is. InputError naming a pattern that matches nothing.
std::vector<std::string> expand_brush_files(const std::vector<std::string>& specs);

// Reads one brush as RGBA8 (grey to RGB, alpha 255 where the file has none; float and 16-bit sources
// as store::read_image8 converts them, linear). InputError naming the file.
Rgba8 read_brush(const std::string& path);

}  // namespace vtsim::produce
