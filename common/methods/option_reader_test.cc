#include "common/methods/option_reader.h"

#include <gtest/gtest.h>

namespace reenact::methods {
namespace {

TEST(OptionReader, ReadsTypedValuesAndRejectsUnknownKeys) {
  const std::map<std::string, std::string> options = {
      {"lambda", "0.25"}, {"segments", "12"}, {"bake", "false"}, {"name", "x"}};
  OptionReader reader(options);
  double lambda = 0.5;
  int segments = 24, rings = 8;
  bool bake = true;
  std::string name;
  EXPECT_TRUE(reader.Double("lambda", &lambda, 0, 10).ok());
  EXPECT_TRUE(reader.Int("segments", &segments, 3, 100).ok());
  EXPECT_TRUE(reader.Int("rings", &rings).ok());  // Absent: unchanged.
  EXPECT_TRUE(reader.Bool("bake", &bake).ok());
  EXPECT_TRUE(reader.String("name", &name).ok());
  EXPECT_TRUE(reader.Finish().ok());
  EXPECT_DOUBLE_EQ(lambda, 0.25);
  EXPECT_EQ(segments, 12);
  EXPECT_EQ(rings, 8);
  EXPECT_FALSE(bake);
  EXPECT_EQ(name, "x");

  const std::map<std::string, std::string> bad = {
      {"segments", "twelve"}, {"lambda", "1e400"}, {"rings", "0"}, {"mystery", "1"}};
  OptionReader bad_reader(bad);
  EXPECT_EQ(bad_reader.Int("segments", &segments).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(bad_reader.Double("lambda", &lambda).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(bad_reader.Int("rings", &rings, 1, 10).code(), absl::StatusCode::kInvalidArgument);
  const absl::Status finish = bad_reader.Finish();
  EXPECT_EQ(finish.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(finish.message().find("mystery"), std::string::npos) << finish;
}

TEST(OptionReader, ABoolIsExactlyTrueOrFalse) {
  for (const std::string word : {"yes", "y", "t", "1", "True", "no", "0", ""}) {
    const std::map<std::string, std::string> options = {{"bake", word}};
    OptionReader reader(options);
    bool bake = true;
    const absl::Status status = reader.Bool("bake", &bake);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << word;
    EXPECT_NE(status.message().find("is not true or false"), std::string::npos) << status;
    EXPECT_TRUE(bake) << word;  // Left as it was.
  }
  const std::map<std::string, std::string> options = {{"bake", "true"}};
  OptionReader reader(options);
  bool bake = false;
  EXPECT_TRUE(reader.Bool("bake", &bake).ok());
  EXPECT_TRUE(bake);
}

struct Example {
  double lambda = 0.5;
  int segments = 24;
  bool bake = true;
  std::string model = "procedural";
  absl::Status Read(OptionReader& reader) {
    if (absl::Status s = reader.Double("lambda", &lambda, 0.0, 10.0, "a weight"); !s.ok()) return s;
    if (absl::Status s = reader.Int("segments", &segments, 3, 100, "around"); !s.ok()) return s;
    if (absl::Status s = reader.Bool("bake", &bake, "bake textures"); !s.ok()) return s;
    return reader.String("model", &model, "which model");
  }
  absl::Status Validate() const {
    return segments % 2 == 0 ? absl::OkStatus() : absl::InvalidArgumentError("segments is odd");
  }
};

TEST(OptionReader, DescribesWhatItParsesWithTheStructsDefaults) {
  const std::vector<OptionSpec> specs = DescribeOptions<Example>();
  ASSERT_EQ(specs.size(), 4u);
  EXPECT_EQ(specs[0].name, "lambda");
  EXPECT_EQ(specs[0].type, OptionType::kDouble);
  EXPECT_EQ(specs[0].default_value, "0.5");
  EXPECT_TRUE(specs[0].has_bounds);
  EXPECT_DOUBLE_EQ(specs[0].max, 10.0);
  EXPECT_EQ(specs[0].doc, "a weight");
  EXPECT_EQ(specs[1].default_value, "24");
  EXPECT_EQ(specs[2].type, OptionType::kBool);
  EXPECT_EQ(specs[2].default_value, "true");
  EXPECT_FALSE(specs[2].has_bounds);
  EXPECT_EQ(specs[3].default_value, "procedural");

  // Every default, given back as text, parses to the same struct.
  OptionMap defaults;
  for (const OptionSpec& spec : specs) defaults[spec.name] = spec.default_value;
  Example parsed;
  parsed.lambda = 9.0;
  parsed.segments = 4;
  parsed.bake = false;
  parsed.model = "x";
  ASSERT_TRUE(ParseOptions(defaults, &parsed).ok());
  EXPECT_DOUBLE_EQ(parsed.lambda, 0.5);
  EXPECT_EQ(parsed.segments, 24);
  EXPECT_TRUE(parsed.bake);
  EXPECT_EQ(parsed.model, "procedural");
}

TEST(OptionReader, ParseOptionsRejectsUnknownKeysNamingTheKnownOnesThenValidates) {
  Example out;
  const absl::Status unknown = ParseOptions(OptionMap{{"lamda", "1"}}, &out);
  EXPECT_EQ(unknown.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(unknown.message().find("lamda"), std::string::npos) << unknown;
  EXPECT_NE(unknown.message().find("known: bake, lambda, model, segments"), std::string::npos)
      << unknown;
  const absl::Status odd = ParseOptions(OptionMap{{"segments", "7"}}, &out);
  EXPECT_EQ(odd.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(odd.message().find("odd"), std::string::npos) << odd;
}

TEST(MethodSpec, UnknownMethodsAreNamedWithTheKnownOnes) {
  const std::vector<MethodSpec> specs = {{"a", "", "", false, TextureMode::kPoseClosest, {}},
                                         {"b", "", "", true, TextureMode::kBodyAtlas, {}}};
  EXPECT_EQ(FindMethod(specs, "b"), &specs[1]);
  EXPECT_EQ(FindMethod(specs, "c"), nullptr);
  const absl::Status error = UnknownMethodError(specs, std::string(200, 'x'));
  EXPECT_EQ(error.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(error.message().find("(known: a, b)"), std::string::npos) << error;
  EXPECT_LT(error.message().size(), 140u) << error;
}

TEST(MethodSpec, CheckOptionsGoesByTheListedTypesAndBounds) {
  MethodSpec spec{"m", "", "", false, TextureMode::kRotationClosest, DescribeOptions<Example>()};
  EXPECT_TRUE(CheckOptions(spec, {{"lambda", "10"}, {"segments", "3"}, {"bake", "false"}}).ok());
  for (const auto& [key, value] :
       std::vector<std::pair<std::string, std::string>>{{"lambda", "10.5"},
                                                        {"lambda", "nan"},
                                                        {"segments", "2"},
                                                        {"segments", "3.5"},
                                                        {"bake", "maybe"},
                                                        {"bake", "no"},
                                                        {"colour", "red"}}) {
    const absl::Status status = CheckOptions(spec, {{key, value}});
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << key << "=" << value;
    EXPECT_NE(status.message().find(key), std::string::npos) << status;
  }
}

}  // namespace
}  // namespace reenact::methods
