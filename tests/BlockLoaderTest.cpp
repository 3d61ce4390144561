#include "BlockLoader.h"

#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>

using namespace seasonview;

namespace {

// A slow source: each read takes `delayMs` and waits while the gate is closed; texel (x, y) of layer L at level l
// is (x, y, 16 L + l) mod 256.
class SlowSource final : public BlockSource {
public:
    explicit SlowSource(int delayMs, bool gateOpen = true) : m_delay(delayMs), m_open(gateOpen) {}
    int layers() const override { return 2; }
    void openGate() {
        {
            std::lock_guard lock(m_mutex);
            m_open = true;
        }
        m_cv.notify_all();
    }
    Status read(int layer, int level, const TexelRect& t, std::uint8_t* rgba) override {
        {
            std::unique_lock lock(m_mutex);
            m_cv.wait(lock, [&] { return m_open; });
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(m_delay));
        if (level == 1 && t.x0 == 0 && t.y0 == 0 && failFirstBlockOfLevel1) return Error{"fake.tif: read failed"};
        size_t i = 0;
        for (int y = t.y0; y < t.y1; ++y)
            for (int x = t.x0; x < t.x1; ++x, ++i) {
                rgba[i * 4 + 0] = std::uint8_t(x);
                rgba[i * 4 + 1] = std::uint8_t(y);
                rgba[i * 4 + 2] = std::uint8_t(16 * layer + level);
                rgba[i * 4 + 3] = 255;
            }
        return Ok{};
    }
    bool failFirstBlockOfLevel1 = false;

private:
    int m_delay;
    std::mutex m_mutex;
    std::condition_variable m_cv;
    bool m_open;
};

} // namespace

TEST(BlockLoaderTest, NeverBlocksAndRespectsTheBudget) {
    SlowSource source(1, false); // reads block until the gate opens: the disk is "stuck"
    ClipmapSchedule schedule(makeClipmapLayout(2048, 2048, 256, 64));
    schedule.setCenters(std::vector<glm::dvec2>(size_t(schedule.layout().clipLevels()), glm::dvec2(1024, 1024)));
    BlockLoader loader(source, schedule);
    const auto wanted = schedule.missingBlocks(1000);
    ASSERT_EQ(wanted.size(), 3u * 16u); // 3 toroidal levels of 4x4 blocks
    // With every read stuck, want() and take() still return (were they to wait for a read, this would hang).
    loader.want(wanted);
    loader.want(wanted);
    EXPECT_TRUE(loader.take(1 << 20).empty());
    EXPECT_EQ(loader.pending(), wanted.size());
    source.openGate();
    loader.waitIdle();
    EXPECT_EQ(loader.pending(), 0u);
    // Budget: 3 blocks of 64² = 12288 texels per take.
    std::vector<LoadedBlock> all;
    while (true) {
        auto batch = loader.take(3 * 64 * 64);
        if (batch.empty()) break;
        EXPECT_LE(batch.size(), 3u);
        for (auto& b : batch) all.push_back(std::move(b));
    }
    ASSERT_EQ(all.size(), wanted.size());
    // Order = priority (finest level first), contents = the source's.
    EXPECT_EQ(all.front().key.level, 0);
    for (const LoadedBlock& b : all) {
        ASSERT_TRUE(b.error.empty());
        ASSERT_EQ(b.layers.size(), 2u);
        const auto& px = b.layers[1];
        EXPECT_EQ(px[0], std::uint8_t(b.texels.x0));
        EXPECT_EQ(px[1], std::uint8_t(b.texels.y0));
        EXPECT_EQ(px[2], std::uint8_t(16 + b.key.level));
    }
    EXPECT_EQ(loader.blocksRead(), std::int64_t(wanted.size()));
}

TEST(BlockLoaderTest, UnwantedBlocksAreDroppedAndNothingIsAskedTwice) {
    SlowSource source(5);
    ClipmapSchedule schedule(makeClipmapLayout(4096, 4096, 256, 64));
    schedule.setCenters(std::vector<glm::dvec2>(size_t(schedule.layout().clipLevels()), glm::dvec2(500, 500)));
    BlockLoader loader(source, schedule);
    const auto a = schedule.missingBlocks(1000);
    loader.want(a);
    loader.want(a); // again: no duplicates
    // The view jumps far away: the old queue is replaced.
    schedule.setCenters(std::vector<glm::dvec2>(size_t(schedule.layout().clipLevels()), glm::dvec2(3500, 3500)));
    const auto b = schedule.missingBlocks(1000);
    loader.want(b);
    loader.waitIdle();
    const auto done = loader.take(1 << 30);
    EXPECT_LE(done.size(), b.size() + 2) << "at most the blocks already in flight of the old view got read";
    EXPECT_GE(done.size(), b.size());
    for (size_t i = 0; i < done.size(); ++i)
        for (size_t j = i + 1; j < done.size(); ++j) EXPECT_FALSE(done[i].key == done[j].key);
}

TEST(BlockLoaderTest, ReadErrorsAreReportedNotFatal) {
    SlowSource source(0);
    source.failFirstBlockOfLevel1 = true;
    ClipmapSchedule schedule(makeClipmapLayout(2048, 2048, 256, 64));
    schedule.setCenters(std::vector<glm::dvec2>(size_t(schedule.layout().clipLevels()), glm::dvec2(0, 0)));
    BlockLoader loader(source, schedule);
    loader.want(schedule.missingBlocks(1000));
    loader.waitIdle();
    int errors = 0;
    for (const auto& b : loader.take(1 << 30)) errors += b.error.empty() ? 0 : 1;
    EXPECT_EQ(errors, 1);
    EXPECT_EQ(loader.readErrors(), 1);
}
