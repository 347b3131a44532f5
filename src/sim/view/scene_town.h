#pragma once
// The deterministic test town (docs/view.md): a textured ground grid, box buildings on a grid of
// city blocks, and free-standing walls along the streets, so that surfaces occlude each other at
// every distance. Every face owns a unique rectangle of the virtual texture (Yao 2011's
// megatexture: no texel is shared), at the terrain's texel density.
#include "sim/view/mesh.h"
#include "sim/view/scene.h"

namespace vtsim {

// Layout: the town covers [0, S]² from the terrain origin, S = blocks·(block + street) + street,
// on ground z = 0. The ground uses the terrain's planar mapping u = floor((x − x0)·tpm) (texels
// [0, S·tpm)); walls and roofs are shelf-packed above it with 4-texel gaps (crazii 2017's border).
// Throws InputError naming the field for out-of-range town parameters or when the faces do not
// fit into the texture. Same config, same mesh, bit for bit.
Mesh generate_town(const SceneConfig& cfg);

// Side length S of the town square, metres.
double town_size_m(const SceneConfig& cfg);

}  // namespace vtsim
