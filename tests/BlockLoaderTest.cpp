#include "BlockLoader.h"

#include <gtest/gtest.h>

#include <atomic>
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

TEST(BlockLoaderTest, FinishedBlocksStayUnderTheCapUntilTaken) {
    // A loader faster than the uploads must not pile up finished blocks: with a cap of 3 blocks it reads 3 (plus
    // at most the one in flight when the cap was reached) and waits until blocks are taken.
    SlowSource source(0);
    ClipmapSchedule schedule(makeClipmapLayout(2048, 2048, 256, 64));
    schedule.setCenters(std::vector<glm::dvec2>(size_t(schedule.layout().clipLevels()), glm::dvec2(1024, 1024)));
    const std::int64_t blockBytes = 2 * 64 * 64 * 4; // two layers of 64² RGBA8
    BlockLoader loader(source, schedule, 3 * blockBytes);
    const auto wanted = schedule.missingBlocks(1000);
    loader.want(wanted);
    loader.waitIdle(); // returns at the cap, not after all 48
    std::this_thread::sleep_for(std::chrono::milliseconds(50)); // a worker ignoring the cap would read on
    EXPECT_EQ(loader.finishedBytes(), 3 * blockBytes);
    EXPECT_EQ(loader.blocksRead(), 3);
    EXPECT_EQ(loader.pending(), wanted.size() - 3);
    // Taking blocks lets it go on; all of them arrive in the end, each once.
    std::vector<BlockKey> got;
    while (got.size() < wanted.size()) {
        loader.waitIdle();
        auto batch = loader.take(1 << 30);
        ASSERT_FALSE(batch.empty());
        EXPECT_LE(std::int64_t(batch.size()) * blockBytes, 3 * blockBytes);
        for (const auto& b : batch) got.push_back(b.key);
    }
    EXPECT_EQ(loader.blocksRead(), std::int64_t(wanted.size()));
    EXPECT_EQ(loader.finishedBytes(), 0);
}

TEST(BlockLoaderTest, FinishedBlocksTheViewLeftAreDroppedAtTheNextWant) {
    SlowSource source(0);
    ClipmapSchedule schedule(makeClipmapLayout(4096, 4096, 256, 64));
    const auto levels = size_t(schedule.layout().clipLevels());
    schedule.setCenters(std::vector<glm::dvec2>(levels, glm::dvec2(500, 500)));
    BlockLoader loader(source, schedule);
    loader.want(schedule.missingBlocks(1000));
    loader.waitIdle();
    const std::int64_t before = loader.finishedBytes();
    ASSERT_GT(before, 0);
    // Nothing taken; the view jumps to the far corner, where the finest level's window shares no block with the
    // old one: its finished blocks go, the coarsest level's (whose window covers the image) stay.
    schedule.setCenters(std::vector<glm::dvec2>(levels, glm::dvec2(3500, 3500)));
    loader.want({});
    EXPECT_LT(loader.finishedBytes(), before);
    for (const LoadedBlock& b : loader.take(1 << 30))
        EXPECT_EQ(intersect(schedule.window(b.key.level), b.texels), b.texels) << "a block outside its window";
}

namespace {

// A source whose reads wait `delayMs` (a network's round trip) and count how many run at once.
class ConcurrentSource final : public BlockSource {
public:
    int layers() const override { return 1; }
    Status read(int, int level, const TexelRect& t, std::uint8_t* rgba) override {
        const int now = ++m_running;
        int seen = m_most.load();
        while (now > seen && !m_most.compare_exchange_weak(seen, now)) {
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
        for (size_t i = 0; i < size_t(t.area()); ++i) {
            rgba[i * 4 + 0] = std::uint8_t(t.x0 / 64);
            rgba[i * 4 + 1] = std::uint8_t(t.y0 / 64);
            rgba[i * 4 + 2] = std::uint8_t(level);
            rgba[i * 4 + 3] = 255;
        }
        --m_running;
        return Ok{};
    }
    int most() const { return m_most.load(); }

private:
    std::atomic<int> m_running{0}, m_most{0};
};

} // namespace

TEST(BlockLoaderTest, SeveralWorkersReadAtOnceEachBlockOnce) {
    // Streamed levels (a service's round trips): 4 workers keep several reads in flight, and every wanted block
    // still arrives once, with its own texels.
    ConcurrentSource source;
    ClipmapSchedule schedule(makeClipmapLayout(2048, 2048, 256, 64));
    schedule.setCenters(std::vector<glm::dvec2>(size_t(schedule.layout().clipLevels()), glm::dvec2(1024, 1024)));
    BlockLoader loader(source, schedule, std::int64_t(64) << 20, 4);
    const auto wanted = schedule.missingBlocks(1000);
    loader.want(wanted);
    loader.want(wanted); // again: nothing asked twice
    loader.waitIdle();
    EXPECT_EQ(loader.pending(), 0u);
    const auto done = loader.take(std::int64_t(1) << 30);
    ASSERT_EQ(done.size(), wanted.size());
    for (size_t i = 0; i < done.size(); ++i) {
        ASSERT_TRUE(done[i].error.empty());
        const auto& px = done[i].layers[0];
        EXPECT_EQ(px[0], std::uint8_t(done[i].texels.x0 / 64));
        EXPECT_EQ(px[1], std::uint8_t(done[i].texels.y0 / 64));
        EXPECT_EQ(px[2], std::uint8_t(done[i].key.level));
        for (size_t j = i + 1; j < done.size(); ++j) EXPECT_FALSE(done[i].key == done[j].key);
    }
    EXPECT_EQ(loader.blocksRead(), std::int64_t(wanted.size()));
    EXPECT_GE(source.most(), 2) << "reads in flight at once";
    EXPECT_LE(source.most(), 4);
}
