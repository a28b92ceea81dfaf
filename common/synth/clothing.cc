#include "common/synth/clothing.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "common/body/joint_set.h"

namespace reenact::synth {
namespace {

using body::KinectV2Joint;
using J = KinectV2Joint;

struct Bone {
  J from, to;
  ClothingRegion region;
};

// Bones of the canonical skeleton with the garment that covers them.
const std::vector<Bone>& ClothingBones() {
  static const std::vector<Bone> bones = {
      {J::kSpineBase, J::kSpineMid, ClothingRegion::kShirt},
      {J::kSpineMid, J::kSpineShoulder, ClothingRegion::kShirt},
      {J::kSpineShoulder, J::kShoulderLeft, ClothingRegion::kShirt},
      {J::kSpineShoulder, J::kShoulderRight, ClothingRegion::kShirt},
      {J::kSpineShoulder, J::kNeck, ClothingRegion::kSkin},
      {J::kNeck, J::kHead, ClothingRegion::kSkin},
      {J::kShoulderLeft, J::kElbowLeft, ClothingRegion::kSleeve},
      {J::kShoulderRight, J::kElbowRight, ClothingRegion::kSleeve},
      {J::kElbowLeft, J::kWristLeft, ClothingRegion::kSkin},
      {J::kElbowRight, J::kWristRight, ClothingRegion::kSkin},
      {J::kWristLeft, J::kHandTipLeft, ClothingRegion::kSkin},
      {J::kWristRight, J::kHandTipRight, ClothingRegion::kSkin},
      {J::kSpineBase, J::kHipLeft, ClothingRegion::kTrousers},
      {J::kSpineBase, J::kHipRight, ClothingRegion::kTrousers},
      {J::kHipLeft, J::kKneeLeft, ClothingRegion::kTrousers},
      {J::kHipRight, J::kKneeRight, ClothingRegion::kTrousers},
      {J::kKneeLeft, J::kAnkleLeft, ClothingRegion::kTrousers},
      {J::kKneeRight, J::kAnkleRight, ClothingRegion::kTrousers},
      {J::kAnkleLeft, J::kFootLeft, ClothingRegion::kShoe},
      {J::kAnkleRight, J::kFootRight, ClothingRegion::kShoe},
  };
  return bones;
}

double SegmentDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                       const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-12), 0.0, 1.0);
  return (p - (a + t * ab)).norm();
}

std::array<Eigen::Vector3d, body::kNumKinectV2Joints> RestJoints(const body::BodyModel& model) {
  std::array<Eigen::Vector3d, body::kNumKinectV2Joints> joints;
  const Eigen::MatrixXd j = model.joint_regressor * model.template_vertices_m.transpose();
  for (int i = 0; i < body::kNumKinectV2Joints; ++i) joints[i] = j.row(i).transpose();
  return joints;
}

// Refines the bone-based region with landmarks: trousers start a little above
// the pelvis, shoes below the ankle, hair on the top and back of the head.
ClothingRegion RefineRegion(ClothingRegion region, const Eigen::Vector3d& p,
                            const std::array<Eigen::Vector3d, body::kNumKinectV2Joints>& joints) {
  const double waist_y = joints[body::Index(J::kSpineBase)].y() + 0.04;
  const double ankle_y =
      0.5 * (joints[body::Index(J::kAnkleLeft)].y() + joints[body::Index(J::kAnkleRight)].y());
  if (region == ClothingRegion::kShirt && p.y() < waist_y) return ClothingRegion::kTrousers;
  if (region == ClothingRegion::kTrousers && p.y() < ankle_y + 0.02) return ClothingRegion::kShoe;
  if (region == ClothingRegion::kSkin) {
    const Eigen::Vector3d& head = joints[body::Index(J::kHead)];
    const Eigen::Vector3d d = p - head;
    if (d.y() > 0.03 || (d.y() > -0.06 && d.z() < -0.04)) return ClothingRegion::kHair;
  }
  return region;
}

// Colour of a point of the rest surface: a pattern per region, varying with
// the rest position so that misplaced texture is visible.
std::array<uint8_t, 3> RegionColor(ClothingRegion region, const Eigen::Vector3d& p) {
  switch (region) {
    case ClothingRegion::kSkin:
      return {224, 172, 138};
    case ClothingRegion::kHair:
      return {58, 38, 26};
    case ClothingRegion::kShirt: {
      // 5 cm horizontal stripes, red and white, with a thin dark pinstripe.
      const double band = std::fmod(p.y() / 0.05 + 1000.0, 2.0);
      if (std::abs(band - 1.0) < 0.06) return {40, 40, 60};
      return band < 1.0 ? std::array<uint8_t, 3>{200, 30, 40}
                        : std::array<uint8_t, 3>{235, 235, 225};
    }
    case ClothingRegion::kSleeve:
      return {20, 140, 140};
    case ClothingRegion::kTrousers: {
      // Denim blue with a 4 cm diagonal check.
      const bool check = (static_cast<int>(std::floor((p.y() + p.x()) / 0.04)) +
                          static_cast<int>(std::floor((p.y() - p.z()) / 0.04))) %
                             2 ==
                         0;
      return check ? std::array<uint8_t, 3>{40, 60, 120} : std::array<uint8_t, 3>{60, 85, 150};
    }
    case ClothingRegion::kShoe:
      return p.y() < 0.02 ? std::array<uint8_t, 3>{230, 230, 230}
                          : std::array<uint8_t, 3>{25, 25, 25};
  }
  return {255, 0, 255};
}

using Rgb = std::array<uint8_t, 3>;

// A hash of an integer cell to [0, 1), for patterns placed in 3D.
double CellHash(int x, int y, int z, int salt) {
  uint32_t h = static_cast<uint32_t>(x) * 73856093u ^ static_cast<uint32_t>(y) * 19349663u ^
               static_cast<uint32_t>(z) * 83492791u ^ static_cast<uint32_t>(salt) * 2654435761u;
  h ^= h >> 13;
  h *= 0x5bd1e995u;
  h ^= h >> 15;
  return (h & 0xffffff) / static_cast<double>(0x1000000);
}

// Scattered dots on `base`: one dot per `cell_m` cube of the rest space, at a
// random place in it, 0.25..0.65 of the cell across, in one of `inks`.
Rgb Dots(const Eigen::Vector3d& p, double cell_m, const Rgb& base, const std::vector<Rgb>& inks) {
  const Eigen::Vector3d q = p / cell_m;
  const int cx = static_cast<int>(std::floor(q.x()));
  const int cy = static_cast<int>(std::floor(q.y()));
  const int cz = static_cast<int>(std::floor(q.z()));
  for (int dz = -1; dz <= 1; ++dz) {
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const int x = cx + dx, y = cy + dy, z = cz + dz;
        const Eigen::Vector3d centre(x + CellHash(x, y, z, 1), y + CellHash(x, y, z, 2),
                                     z + CellHash(x, y, z, 3));
        const double radius = 0.5 * (0.25 + 0.4 * CellHash(x, y, z, 4));
        if ((q - centre).norm() < radius) {
          return inks[static_cast<size_t>(CellHash(x, y, z, 5) * inks.size()) % inks.size()];
        }
      }
    }
  }
  return base;
}

// Blotches: the colour of the nearest of jittered cell centres (`cell_m`
// apart), one of `colours` per cell.
Rgb Blotches(const Eigen::Vector3d& p, double cell_m, const std::vector<Rgb>& colours) {
  const Eigen::Vector3d q = p / cell_m;
  const int cx = static_cast<int>(std::floor(q.x()));
  const int cy = static_cast<int>(std::floor(q.y()));
  const int cz = static_cast<int>(std::floor(q.z()));
  double best = 1e9;
  Rgb out = colours.front();
  for (int dz = -1; dz <= 1; ++dz) {
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const int x = cx + dx, y = cy + dy, z = cz + dz;
        const Eigen::Vector3d centre(x + CellHash(x, y, z, 6), y + CellHash(x, y, z, 7),
                                     z + CellHash(x, y, z, 8));
        const double d = (q - centre).squaredNorm();
        if (d < best) {
          best = d;
          out =
              colours[static_cast<size_t>(CellHash(x, y, z, 9) * colours.size()) % colours.size()];
        }
      }
    }
  }
  return out;
}

// Two colours in bands `period_m` apart along `coordinate` (the first half
// of each period `a`).
Rgb Bands(double coordinate, double period_m, const Rgb& a, const Rgb& b) {
  const double phase = std::fmod(coordinate / period_m + 1000.0, 1.0);
  return phase < 0.5 ? a : b;
}

// Colour of a point of the rest surface in `wardrobe`.
Rgb WardrobeColor(Wardrobe wardrobe, ClothingRegion region, const Eigen::Vector3d& p) {
  const bool garment = region == ClothingRegion::kShirt || region == ClothingRegion::kSleeve ||
                       region == ClothingRegion::kTrousers;
  if (wardrobe == Wardrobe::kDefault || !garment) return RegionColor(region, p);
  switch (wardrobe) {
    case Wardrobe::kSolid:
      if (region == ClothingRegion::kShirt) return {214, 168, 48};
      if (region == ClothingRegion::kSleeve) return {46, 120, 70};
      return {62, 62, 70};
    case Wardrobe::kPrint: {
      static const std::vector<Rgb> inks = {
          {200, 40, 70}, {30, 90, 170}, {240, 170, 30}, {40, 140, 90}};
      static const std::vector<Rgb> camo = {
          {96, 104, 60}, {132, 116, 78}, {58, 66, 44}, {160, 150, 110}};
      if (region == ClothingRegion::kTrousers) return Blotches(p, 0.06, camo);
      return Dots(p, 0.05, {236, 228, 210}, inks);
    }
    case Wardrobe::kStripes:
      if (region == ClothingRegion::kShirt)
        return Bands(p.y(), 0.04, {25, 35, 90}, {240, 240, 235});
      if (region == ClothingRegion::kSleeve)
        return Bands(p.x(), 0.03, {200, 40, 40}, {245, 220, 60});
      return Bands(p.x() + p.z(), 0.02, {30, 30, 40}, {190, 190, 200});
    case Wardrobe::kDefault:
      break;
  }
  return RegionColor(region, p);
}

// Grows painted texels into unpainted ones, `passes` pixels deep.
void Dilate(RgbImage* image, std::vector<uint8_t>* painted, int passes) {
  const int w = image->width, h = image->height;
  for (int pass = 0; pass < passes; ++pass) {
    std::vector<uint8_t> next = *painted;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        if ((*painted)[y * w + x]) continue;
        const int nx[4] = {x - 1, x + 1, x, x}, ny[4] = {y, y, y - 1, y + 1};
        for (int n = 0; n < 4; ++n) {
          if (nx[n] < 0 || ny[n] < 0 || nx[n] >= w || ny[n] >= h ||
              !(*painted)[ny[n] * w + nx[n]]) {
            continue;
          }
          for (int c = 0; c < 3; ++c) image->at(x, y, c) = image->at(nx[n], ny[n], c);
          next[y * w + x] = 1;
          break;
        }
      }
    }
    *painted = std::move(next);
  }
}

}  // namespace

std::vector<ClothingRegion> ClassifyClothingRegions(const body::BodyModel& model) {
  const auto joints = RestJoints(model);
  std::vector<ClothingRegion> regions(model.triangles.size(), ClothingRegion::kSkin);
  for (size_t t = 0; t < model.triangles.size(); ++t) {
    const Eigen::Vector3i& tri = model.triangles[t];
    const Eigen::Vector3d c =
        (model.template_vertices_m.col(tri[0]) + model.template_vertices_m.col(tri[1]) +
         model.template_vertices_m.col(tri[2])) /
        3.0;
    double best = 1e9;
    for (const Bone& bone : ClothingBones()) {
      const double d =
          SegmentDistance(c, joints[body::Index(bone.from)], joints[body::Index(bone.to)]);
      if (d < best) {
        best = d;
        regions[t] = bone.region;
      }
    }
    regions[t] = RefineRegion(regions[t], c, joints);
  }
  return regions;
}

absl::StatusOr<Wardrobe> ParseWardrobe(const std::string& name) {
  for (Wardrobe w : {Wardrobe::kDefault, Wardrobe::kSolid, Wardrobe::kPrint, Wardrobe::kStripes}) {
    if (name == WardrobeName(w)) return w;
  }
  return absl::InvalidArgumentError(
      "wardrobe must be one of default, solid, print, stripes, not \"" + name + "\"");
}

std::string WardrobeName(Wardrobe wardrobe) {
  switch (wardrobe) {
    case Wardrobe::kDefault:
      return "default";
    case Wardrobe::kSolid:
      return "solid";
    case Wardrobe::kPrint:
      return "print";
    case Wardrobe::kStripes:
      return "stripes";
  }
  return "default";
}

RgbImage PaintClothingTexture(const body::BodyModel& model, int size, Wardrobe wardrobe) {
  RgbImage image(size, size, 128);
  std::vector<uint8_t> painted(static_cast<size_t>(size) * size, 0);
  const std::vector<ClothingRegion> regions = ClassifyClothingRegions(model);
  for (size_t t = 0; t < model.triangles.size() && t < model.uv_triangles.size(); ++t) {
    const Eigen::Vector3i& tri = model.triangles[t];
    const Eigen::Vector3i& uvt = model.uv_triangles[t];
    Eigen::Vector2d uv[3];
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector2f& q = model.uvs[uvt[k]];
      uv[k] = {q.x() * size - 0.5, (1.0 - q.y()) * size - 0.5};  // Texel centres.
    }
    const double area =
        (uv[1] - uv[0]).x() * (uv[2] - uv[0]).y() - (uv[1] - uv[0]).y() * (uv[2] - uv[0]).x();
    if (std::abs(area) < 1e-12) continue;
    const int x0 =
        std::max(0, static_cast<int>(std::floor(std::min({uv[0].x(), uv[1].x(), uv[2].x()}))));
    const int x1 = std::min(
        size - 1, static_cast<int>(std::ceil(std::max({uv[0].x(), uv[1].x(), uv[2].x()}))));
    const int y0 =
        std::max(0, static_cast<int>(std::floor(std::min({uv[0].y(), uv[1].y(), uv[2].y()}))));
    const int y1 = std::min(
        size - 1, static_cast<int>(std::ceil(std::max({uv[0].y(), uv[1].y(), uv[2].y()}))));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const Eigen::Vector2d p(x, y);
        auto edge = [&](int a, int b) {
          return ((uv[b] - uv[a]).x() * (p - uv[a]).y() - (uv[b] - uv[a]).y() * (p - uv[a]).x()) /
                 area;
        };
        const double w0 = edge(1, 2), w1 = edge(2, 0), w2 = edge(0, 1);
        const double tolerance = -0.02;  // Slightly conservative, closes hairline gaps.
        if (w0 < tolerance || w1 < tolerance || w2 < tolerance) continue;
        const Eigen::Vector3d pos = w0 * model.template_vertices_m.col(tri[0]) +
                                    w1 * model.template_vertices_m.col(tri[1]) +
                                    w2 * model.template_vertices_m.col(tri[2]);
        const auto rgb = WardrobeColor(wardrobe, regions[t], pos);
        for (int c = 0; c < 3; ++c) image.at(x, y, c) = rgb[c];
        painted[static_cast<size_t>(y) * size + x] = 1;
      }
    }
  }
  Dilate(&image, &painted, 4);
  return image;
}

}  // namespace reenact::synth
