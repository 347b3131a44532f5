#pragma once
// Feedback image: the desired level of every buffer pixel as a colour (docs/view.md).
#include <array>
#include <string>

#include "core/view.h"

namespace vtsim {

// Colour of a desired level: level 0 red, then orange, yellow, lime, green, cyan, blue, purple,
// magenta, pink, brown, white, repeating every 12 levels. Pixels without a sample are black.
std::array<unsigned char, 3> level_colour(int level);

// Writes the buffer (each pixel repeated zoom × zoom times) as an 8-bit RGB image in any format
// OpenImageIO writes (by extension). Throws InputError(path, ...) when it cannot, or for zoom
// outside [1, 64].
void write_level_image(const std::string& path, const ViewBuffer& vb, int num_levels, int zoom = 1);

}  // namespace vtsim
