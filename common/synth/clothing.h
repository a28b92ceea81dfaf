// The synthetic actor's clothing: a texture over the body model's UV atlas
// with distinct regions (striped shirt, plain sleeves, skin, hair, patterned
// trousers, shoes), so that texturing errors of a reconstruction show up in
// image comparisons. Works for any BodyModel (procedural or MakeHuman): a
// triangle's region follows from the rest-pose bone nearest to it.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "common/body/body_model.h"

namespace reenact::synth {

enum class ClothingRegion : uint8_t { kSkin, kHair, kShirt, kSleeve, kTrousers, kShoe };

// What the actor wears (skin, hair and shoes are the same in every one):
//  kDefault  red and white 5 cm shirt stripes with a dark pinstripe, plain
//            teal sleeves, denim trousers with a 4 cm diagonal check;
//  kSolid    one flat colour per garment (mustard shirt, green sleeves,
//            charcoal trousers): what shading and seams alone cost;
//  kPrint    a print: scattered dots of 1.2-3.3 cm in four colours on a pale
//            shirt and sleeves, large soft blotches (camouflage-like, 6 cm
//            cells) on the trousers; placed in 3D on the rest surface;
//  kStripes  high contrast stripes everywhere: 2 cm horizontal navy and
//            white on the shirt, 1.5 cm bands round the sleeves,
//            1 cm vertical pinstripes on the trousers: what misregistration
//            of a pixel or two costs.
enum class Wardrobe : uint8_t { kDefault, kSolid, kPrint, kStripes };

// "default", "solid", "print", "stripes"; InvalidArgument otherwise.
absl::StatusOr<Wardrobe> ParseWardrobe(const std::string& name);
// The name ParseWardrobe reads.
std::string WardrobeName(Wardrobe wardrobe);

// Region of every triangle of `model` (same order as model.triangles).
std::vector<ClothingRegion> ClassifyClothingRegions(const body::BodyModel& model);

// Paints a `size` x `size` texture over the model's UVs (row 0 = v = 1, the
// top of the image). Texels outside every chart are filled by dilation so
// that bilinear filtering at seams does not bleed black.
// `wardrobe` chooses the garments' patterns (kDefault: the historical
// appearance, pixel for pixel).
RgbImage PaintClothingTexture(const body::BodyModel& model, int size = 1024,
                              Wardrobe wardrobe = Wardrobe::kDefault);

}  // namespace reenact::synth
