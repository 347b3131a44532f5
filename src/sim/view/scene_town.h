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

// The town's name in the scene table (scene.cpp).
inline constexpr char kTownScene[] = "town";

// Side length S of the town square, metres.
double town_size_m(const SceneConfig& cfg);

// `town` repeated tiles × tiles side by side, tile (i, j) shifted by (i, j)·period_m along x and y
// (an instanced town: bench_mesh_scaling's large scenes). Texture coordinates are shared, not
// repeated into new texels; solids are shifted with their tile, infinite ones (the half-space
// under the ground) kept once. tiles ≥ 1; the result has tiles² times the triangles.
Mesh tile_town(const Mesh& town, double period_m, int tiles);

}  // namespace vtsim
