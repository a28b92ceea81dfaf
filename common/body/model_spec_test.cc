#include "common/body/model_spec.h"

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/testing/test_data.h"

namespace reenact::body {
namespace {

TEST(ResolveAssetModelSpec, NamesResolveUnderTheRootsAndPathsNever) {
  const std::string root_a = reenact::testing::MakeTempDir("assets_a");
  const std::string root_b = reenact::testing::MakeTempDir("assets_b");
  std::filesystem::create_directories(root_b + "/teacher-1");
  std::filesystem::create_directories(root_a + "/learner");
  std::ofstream(root_a + "/file_not_folder") << "x";
  const std::vector<std::string> roots = {root_a, root_b};

  EXPECT_EQ(*ResolveAssetModelSpec("procedural", {}), "procedural");
  EXPECT_EQ(*ResolveAssetModelSpec("makehuman:teacher-1", roots),
            "makehuman:" + root_b + "/teacher-1");
  EXPECT_EQ(ListAssetModels(roots), (std::vector<std::string>{"learner", "teacher-1"}));

  for (const std::string& spec :
       {std::string("makehuman:") + root_b + "/teacher-1", std::string("makehuman:../assets_b"),
        std::string("makehuman:.."), std::string("makehuman:."), std::string("makehuman:a/b"),
        std::string("makehuman:"), std::string("smpl"), "makehuman:" + std::string(65, 'a')}) {
    const absl::Status status = ResolveAssetModelSpec(spec, roots).status();
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << spec << ": " << status;
    EXPECT_EQ(status.message().find(root_a), std::string::npos) << status;
  }
  const absl::Status unknown = ResolveAssetModelSpec("makehuman:nobody", roots).status();
  EXPECT_EQ(unknown.code(), absl::StatusCode::kNotFound) << unknown;
  EXPECT_NE(unknown.message().find("makehuman:learner, makehuman:teacher-1"), std::string::npos)
      << unknown;
  EXPECT_EQ(unknown.message().find(root_a), std::string::npos) << unknown;
  EXPECT_EQ(unknown.message().find(root_b), std::string::npos) << unknown;
  EXPECT_EQ(ResolveAssetModelSpec("makehuman:file_not_folder", roots).status().code(),
            absl::StatusCode::kNotFound);
  EXPECT_EQ(ResolveAssetModelSpec("makehuman:learner", {}).status().code(),
            absl::StatusCode::kFailedPrecondition);
}

TEST(LoadAssetModelSpec, LoadsAnAssetAndItsErrorsNameNoServerPath) {
  const std::string body = reenact::testing::TestDataPath("body");
  REENACT_REQUIRE_TEST_FILE(body + "/makehuman");
  const absl::StatusOr<BodyModel> model = LoadAssetModelSpec("makehuman:makehuman", {body});
  ASSERT_TRUE(model.ok()) << model.status();
  EXPECT_GT(model->template_vertices_m.cols(), 1000);

  // A folder that is not a MakeHuman export: the importer's message names
  // its file, which the client sees as the asset's.
  const std::string root = reenact::testing::MakeTempDir("assets_broken");
  std::filesystem::create_directories(root + "/broken/3dobjs");
  std::ofstream(root + "/broken/3dobjs/base.obj") << "v 0 0 zero\n";
  const absl::Status status = LoadAssetModelSpec("makehuman:broken", {root}).status();
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.message().find(root), std::string::npos) << status;
  EXPECT_NE(status.message().find("makehuman:broken"), std::string::npos) << status;
}

}  // namespace
}  // namespace reenact::body
