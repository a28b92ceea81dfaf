#include "common/synth/clothing.h"

#include <set>

#include <gtest/gtest.h>

#include "common/body/procedural_body.h"
#include "common/synth/synthesizer.h"

namespace reenact::synth {
namespace {

// Distinct colours of an image.
size_t CountColours(const RgbImage& image) {
  std::set<int> colours;
  for (size_t i = 0; i + 2 < image.data.size(); i += 3) {
    colours.insert(image.data[i] << 16 | image.data[i + 1] << 8 | image.data[i + 2]);
  }
  return colours.size();
}

TEST(ParseWardrobe, ReadsEveryNameAndRefusesOthers) {
  for (Wardrobe w : {Wardrobe::kDefault, Wardrobe::kSolid, Wardrobe::kPrint, Wardrobe::kStripes}) {
    auto parsed = ParseWardrobe(WardrobeName(w));
    ASSERT_TRUE(parsed.ok()) << parsed.status();
    EXPECT_EQ(*parsed, w);
  }
  EXPECT_EQ(ParseWardrobe("tuxedo").status().code(), absl::StatusCode::kInvalidArgument);
  SynthOptions options;
  options.wardrobe = "tuxedo";
  EXPECT_EQ(options.Validate().code(), absl::StatusCode::kInvalidArgument);
  options.wardrobe = "stripes";
  EXPECT_TRUE(options.Validate().ok());
}

TEST(PaintClothingTexture, WardrobesDifferAndSolidIsFlat) {
  auto model = body::BuildProceduralBody();
  ASSERT_TRUE(model.ok()) << model.status();
  const RgbImage standard = PaintClothingTexture(*model, 256);
  EXPECT_EQ(PaintClothingTexture(*model, 256, Wardrobe::kDefault).data, standard.data);
  const RgbImage solid = PaintClothingTexture(*model, 256, Wardrobe::kSolid);
  const RgbImage print = PaintClothingTexture(*model, 256, Wardrobe::kPrint);
  const RgbImage stripes = PaintClothingTexture(*model, 256, Wardrobe::kStripes);
  EXPECT_NE(solid.data, standard.data);
  EXPECT_NE(print.data, solid.data);
  EXPECT_NE(stripes.data, print.data);
  // Solid: a colour per region (skin, hair, shirt, sleeve, trousers, two
  // shoe colours) and the grey of texels outside every chart.
  EXPECT_LE(CountColours(solid), 8u);
  // The print has four inks and four blotch colours beyond the base.
  EXPECT_GE(CountColours(print), CountColours(solid) + 6);
  EXPECT_GE(CountColours(stripes), CountColours(solid) + 2);
}

}  // namespace
}  // namespace reenact::synth
