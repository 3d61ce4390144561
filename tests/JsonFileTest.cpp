// JSON files are read within limits: nesting deeper than kMaxJsonDepth and files over kMaxJsonBytes are refused
// with the limit named, malformed text with its line and column, and no exception escapes.
#include "JsonFile.h"
#include "TestUtil.h"

#include <gtest/gtest.h>

#include <fstream>

using namespace seasonview;
using namespace seasonview::test;

TEST(JsonFileTest, NestingDeeperThanTheLimitIsRefused) {
    const auto nested = [](int depth) { return std::string(size_t(depth), '[') + std::string(size_t(depth), ']'); };
    EXPECT_TRUE(parseJson(nested(kMaxJsonDepth), "ok.json", "test").ok());
    auto deep = parseJson(nested(kMaxJsonDepth + 1), "deep.json", "test");
    ASSERT_FALSE(deep.ok());
    EXPECT_EQ(deep.message(), "deep.json: JSON nested deeper than 64 levels (the limit)");
    // A million levels: refused at level 65, without walking (or recursing into) the rest.
    auto million = parseJson(std::string(1000000, '['), "million.json", "test");
    ASSERT_FALSE(million.ok());
    EXPECT_NE(million.message().find("deeper than 64"), std::string::npos) << million.message();
}

TEST(JsonFileTest, MalformedTextNamesLineAndColumn) {
    auto r = parseJson("{\n  \"a\": 1,\n  \"b\": ]\n}", "bad.json", "camera path");
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.message(), "bad.json: malformed JSON camera path (line 3, column 8)");
    // Invalid UTF-8 inside a string is malformed too, not an exception.
    auto utf = parseJson("[\"\xff\xfe\"]", "utf.json", "test");
    ASSERT_FALSE(utf.ok());
    EXPECT_NE(utf.message().find("utf.json: malformed JSON test"), std::string::npos);
}

TEST(JsonFileTest, FilesOverTheSizeLimitAreRefusedBeforeReading) {
    TempDir dir("json-limit");
    {
        std::ofstream(dir / "big.json") << "[";
    }
    // Sparse: the file claims its size without the disk holding it.
    std::filesystem::resize_file(dir / "big.json", kMaxJsonBytes + 1);
    auto r = readJsonFile(dir / "big.json", "camera path");
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.message().find("big.json: JSON camera path of 268435457 bytes is over the limit of 256 MiB"), std::string::npos)
        << r.message();
    auto missing = readJsonFile(dir / "none.json", "camera path");
    ASSERT_FALSE(missing.ok());
    EXPECT_EQ(missing.message(), (dir / "none.json").string() + ": file not found");
}

TEST(JsonFileTest, ValuesOfAnotherTypeFallBack) {
    const auto j = nlohmann::json::parse(R"({"n": "seven", "s": 7, "v": [1, "x"]})");
    EXPECT_EQ(jsonValue(j, "n", 3), 3);
    EXPECT_EQ(jsonValue<std::string>(j, "s", "none"), "none");
    EXPECT_EQ(jsonValue(j, "missing", 2.5), 2.5);
    EXPECT_TRUE(jsonValue<std::vector<float>>(j, "v", {}).empty());
    EXPECT_EQ(jsonValue(nlohmann::json(5), "n", 1), 1);
}
