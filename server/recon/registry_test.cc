#include "server/recon/registry.h"

#include <set>

#include <gtest/gtest.h>

#include "absl/strings/str_cat.h"
#include "server/recon/methods.h"

namespace reenact::recon {
namespace {

using methods::OptionSpec;
using methods::OptionType;

TEST(Registry, ListsEachMethodOnceWithWhatTheOtherProcessesNeed) {
  EXPECT_EQ(MethodNames(), (std::vector<std::string>{"rigid-cylinders", "rigid-carved", "body"}));
  for (const methods::MethodSpec& spec : MethodSpecs()) {
    SCOPED_TRACE(spec.name);
    EXPECT_EQ(FindMethod(spec.name)->spec().name, spec.name);
    EXPECT_FALSE(spec.summary.empty());
    EXPECT_FALSE(spec.thesis.empty());
    std::set<std::string> names;
    for (const OptionSpec& option : spec.options) {
      EXPECT_TRUE(names.insert(option.name).second) << option.name << " is listed twice";
      EXPECT_FALSE(option.doc.empty()) << option.name << " has no documentation";
    }
    EXPECT_TRUE(names.count("threads") && names.count("max_frames"));
    // "live" is the request's own field (SubmitJobRequest.live), never an
    // option.
    EXPECT_EQ(names.count("live"), 0u);
  }
  EXPECT_EQ(FindMethod("rigid-cylinders")->spec().texture, methods::TextureMode::kPoseClosest);
  EXPECT_EQ(FindMethod("rigid-carved")->spec().texture, methods::TextureMode::kRotationClosest);
  EXPECT_EQ(FindMethod("body")->spec().texture, methods::TextureMode::kBodyAtlas);
  EXPECT_EQ(FindMethod("nope"), nullptr);
}

// A method that says it can follow a take live makes its own follower; the
// others say they cannot. A method checks the models it names against the
// server's assets itself.
TEST(Registry, MethodsMakeTheirOwnLiveFollowersAndCheckTheirOwnAssets) {
  TakeInfo info;
  info.fps = 30;
  for (const ReconstructionMethod* method : Methods()) {
    SCOPED_TRACE(method->spec().name);
    // No sensors: a follower that exists still refuses them, with its own
    // error rather than Unimplemented.
    const absl::StatusOr<std::unique_ptr<LiveFollower>> follower =
        method->MakeLiveFollower(info, {}, {}, {});
    EXPECT_EQ(absl::IsUnimplemented(follower.status()), !method->spec().live) << follower.status();
    EXPECT_TRUE(method->CheckAssets({}, {}).ok());
  }
  EXPECT_TRUE(FindMethod("body")->spec().live);
  const absl::Status unknown = CheckJob("body", {{"model", "makehuman:nobody"}}, {"/no/such/root"});
  EXPECT_TRUE(absl::IsNotFound(unknown)) << unknown;
  const absl::Status path = CheckJob("body", {{"model", "makehuman:/etc"}}, {"/no/such/root"});
  EXPECT_TRUE(absl::IsInvalidArgument(path)) << path;
  EXPECT_TRUE(CheckJob("body", {{"model", "procedural"}}, {}).ok());
}

// What `reenact jobs methods` lists is what the method parses: every default
// given back as text is accepted, and a value past any listed bound is
// refused naming the option.
TEST(Registry, EveryListedOptionParsesItsDefaultAndRefusesValuesPastItsBounds) {
  for (const methods::MethodSpec& spec : MethodSpecs()) {
    SCOPED_TRACE(spec.name);
    OptionMap defaults;
    for (const OptionSpec& option : spec.options) {
      if (!option.live_only) defaults[option.name] = option.default_value;
    }
    EXPECT_TRUE(CheckJob(spec.name, defaults).ok()) << CheckJob(spec.name, defaults);
    int bounded = 0;
    for (const OptionSpec& option : spec.options) {
      if (option.live_only || !option.has_bounds) continue;
      ++bounded;
      const std::string past =
          option.type == OptionType::kInt
              ? absl::StrCat(static_cast<int64_t>(option.max) + 1)
              : absl::StrCat(option.max + (option.max == 0 ? 1.0 : std::abs(option.max)));
      const absl::Status status = CheckJob(spec.name, {{option.name, past}});
      EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << option.name << "=" << past;
      EXPECT_NE(status.message().find(option.name), std::string::npos) << status;
    }
    EXPECT_GT(bounded, 2);
  }
}

TEST(Registry, UnknownMethodsAndOptionsAreRefusedNamingWhatIsValid) {
  const absl::Status method = CheckJob("rigid-carving", {});
  EXPECT_EQ(method.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(method.message().find("rigid-cylinders, rigid-carved, body"), std::string::npos)
      << method;
  const absl::Status option = CheckJob("rigid-carved", {{"voxel_size", "4"}});
  EXPECT_EQ(option.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(option.message().find("voxel_size"), std::string::npos) << option;
  EXPECT_NE(option.message().find("voxel_mm"), std::string::npos) << option;
  // Across options: Validate() runs at the edge, before any take is read.
  const absl::Status across = CheckJob("rigid-carved", {{"voxel_mm", "30"}, {"mu_mm", "20"}});
  EXPECT_EQ(across.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(across.message().find("mu_mm"), std::string::npos) << across;
  // A body model is an asset name, never a path.
  EXPECT_EQ(CheckJob("body", {{"model", "/etc/passwd"}}).code(),
            absl::StatusCode::kInvalidArgument);
  // The body model belongs to the method body only.
  EXPECT_EQ(CheckJob("rigid-cylinders", {{"model", "procedural"}}).code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reenact::recon
