// The test suite's own asset selection (test_support.hpp): $ISK_TEST_ASSETS
// narrows the asset tests, and a name that is no asset is an error that
// says so rather than a run that silently covers nothing.
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

namespace isk {
namespace {

TEST(AssetSelection, UnsetOrEmptyMeansEveryAsset) {
  EXPECT_EQ(test::assetSelection(nullptr), test::allAssetNames());
  EXPECT_EQ(test::assetSelection(""), test::allAssetNames());
  EXPECT_EQ(test::allAssetNames().size(), 11u);
}

TEST(AssetSelection, AListNamesThoseAssets) {
  const std::vector<std::string> chosen =
      test::assetSelection("fox-animations.glb,,RiggedSimple.dae");
  EXPECT_EQ(chosen, (std::vector<std::string>{"fox-animations.glb",
                                              "RiggedSimple.dae"}));
}

TEST(AssetSelection, AnUnknownNameIsAnErrorThatNamesIt) {
  try {
    test::assetSelection("fox-animations.glb,fox.glb");
    FAIL() << "an unknown asset was accepted";
  } catch (const std::invalid_argument& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("ISK_TEST_ASSETS"), std::string::npos) << message;
    EXPECT_NE(message.find("'fox.glb'"), std::string::npos) << message;
    EXPECT_NE(message.find("human-female.glb"), std::string::npos) << message;
  }
}

TEST(AssetSelection, TheAssetTestsRunOnTheSelectionInTheSuitesOrder) {
  const test::ScopedEnv selection(test::kAssetSelectionVariable,
                                  "human-female.glb,anim_test.x");
  EXPECT_EQ(test::assetNames(),
            (std::vector<std::string>{"anim_test.x", "human-female.glb"}));
  const test::ScopedEnv every(test::kAssetSelectionVariable, "");
  EXPECT_EQ(test::assetNames(), test::allAssetNames());
}

}  // namespace
}  // namespace isk
