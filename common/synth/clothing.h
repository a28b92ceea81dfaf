// The synthetic actor's clothing: a texture over the body model's UV atlas
// with distinct regions (striped shirt, plain sleeves, skin, hair, patterned
// trousers, shoes), so that texturing errors of a reconstruction show up in
// image comparisons. Works for any BodyModel (procedural or MakeHuman): a
// triangle's region follows from the rest-pose bone nearest to it.
#pragma once

#include <cstdint>
#include <vector>

#include "common/base/image.h"
#include "common/body/body_model.h"

namespace reenact::synth {

enum class ClothingRegion : uint8_t { kSkin, kHair, kShirt, kSleeve, kTrousers, kShoe };

// Region of every triangle of `model` (same order as model.triangles).
std::vector<ClothingRegion> ClassifyClothingRegions(const body::BodyModel& model);

// Paints a `size` x `size` texture over the model's UVs (row 0 = v = 1, the
// top of the image). Texels outside every chart are filled by dilation so
// that bilinear filtering at seams does not bleed black.
RgbImage PaintClothingTexture(const body::BodyModel& model, int size = 1024);

}  // namespace reenact::synth
