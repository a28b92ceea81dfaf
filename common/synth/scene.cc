#include "common/synth/scene.h"

#include <cmath>
#include <cstdint>

#include <Eigen/Geometry>

namespace reenact::synth {
namespace {

// A quad from corner `origin` spanned by `u` and `v` (counter-clockwise seen
// from the side the normal u x v points to), uv repeating every `tile_m`.
render::MeshData Quad(const Eigen::Vector3f& origin, const Eigen::Vector3f& u,
                      const Eigen::Vector3f& v, float tile_m, int subdivisions) {
  render::MeshData mesh;
  const int n = subdivisions + 1;
  mesh.positions_m.resize(3, n * n);
  mesh.uvs.resize(2, n * n);
  mesh.normals.resize(3, n * n);
  const Eigen::Vector3f normal = u.cross(v).normalized();
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const float a = static_cast<float>(i) / subdivisions,
                  b = static_cast<float>(j) / subdivisions;
      mesh.positions_m.col(j * n + i) = origin + a * u + b * v;
      mesh.uvs.col(j * n + i) = Eigen::Vector2f(a * u.norm() / tile_m, b * v.norm() / tile_m);
      mesh.normals.col(j * n + i) = normal;
    }
  }
  for (int j = 0; j < subdivisions; ++j) {
    for (int i = 0; i < subdivisions; ++i) {
      const int p = j * n + i;
      mesh.triangles.emplace_back(p, p + 1, p + n + 1);
      mesh.triangles.emplace_back(p, p + n + 1, p + n);
    }
  }
  return mesh;
}

uint8_t Hash(int x, int y) {
  uint32_t h = static_cast<uint32_t>(x) * 374761393u + static_cast<uint32_t>(y) * 668265263u;
  h = (h ^ (h >> 13)) * 1274126177u;
  return static_cast<uint8_t>(h >> 24);
}

// Wooden planks: 20 cm wide boards in three tones with grain and dark joints
// (one tile = 1 m, 256 px).
RgbImage PlankTexture() {
  RgbImage image(256, 256);
  for (int y = 0; y < 256; ++y) {
    for (int x = 0; x < 256; ++x) {
      const int board = x / 51;
      const int tone = Hash(board, (y + board * 97) / 128) % 3;
      const double grain = 8.0 * std::sin(y * 0.35 + board * 1.7 + std::sin(x * 0.2) * 2.0);
      const bool joint = x % 51 == 0 || (y + board * 97) % 128 == 0;
      const int base[3][3] = {{150, 105, 65}, {170, 122, 78}, {132, 92, 58}};
      for (int c = 0; c < 3; ++c) {
        const double value = joint ? 60.0 : base[tone][c] + grain + (Hash(x, y) % 9) - 4;
        image.at(x, y, c) = static_cast<uint8_t>(std::clamp(value, 0.0, 255.0));
      }
    }
  }
  return image;
}

// Plaster with a slight mottle and a dark skirting board at the bottom (one
// tile = 2.6 m tall, so the board sits at v < 0.04).
RgbImage WallTexture() {
  RgbImage image(256, 256);
  for (int y = 0; y < 256; ++y) {
    for (int x = 0; x < 256; ++x) {
      const bool skirting = y > 245;
      const int mottle = (Hash(x / 4, y / 4) % 11) - 5;
      const int base[3] = {214, 208, 190};
      for (int c = 0; c < 3; ++c) {
        image.at(x, y, c) = skirting ? 70 : static_cast<uint8_t>(base[c] + mottle);
      }
    }
  }
  return image;
}

}  // namespace

std::vector<RoomPart> MakeRoom(double floor_size_m, double wall_distance_m) {
  const float s = static_cast<float>(floor_size_m), w = static_cast<float>(wall_distance_m);
  const float h = 2.6f;
  std::vector<RoomPart> room;
  // Floor, normal +Y.
  room.push_back({Quad({-s / 2, 0, s / 2}, {s, 0, 0}, {0, 0, -s}, 1.0f, 8), PlankTexture()});
  // Walls facing the room (normals towards x = 0); uv v = 0 at the floor.
  room.push_back({Quad({-w, 0, s / 2}, {0, 0, -s}, {0, h, 0}, h, 8), WallTexture()});
  room.push_back({Quad({w, 0, -s / 2}, {0, 0, s}, {0, h, 0}, h, 8), WallTexture()});
  return room;
}

}  // namespace reenact::synth
