// The room the synthetic actor performs in: a textured floor and walls, so
// that depth images hold a background (floor plane, walls) to segment the
// actor from, as in a real capture.
#pragma once

#include <vector>

#include "common/base/image.h"
#include "common/render/mesh_data.h"

namespace reenact::synth {

struct RoomPart {
  render::MeshData mesh;  // World frame, metres.
  RgbImage texture;
};

// A floor of `floor_size_m` square centred on the origin at y = 0 (wooden
// planks) and two side walls at x = +-wall_distance_m, 2.6 m high (plaster
// with a skirting board).
std::vector<RoomPart> MakeRoom(double floor_size_m = 9.0, double wall_distance_m = 3.2);

}  // namespace reenact::synth
