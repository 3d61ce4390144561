// sharedFixture (TestUtil.h): made once per build and shared by the test processes; a failed or interrupted make is
// made again, never taken as made; processes asking at once wait for the one making it.
#include "TestUtil.h"

#include <gtest/gtest.h>

#include <fstream>
#include <sys/wait.h>
#include <unistd.h>

using namespace seasonview::test;

namespace {

namespace fs = std::filesystem;

// A name of this process's own, so that runs of the test at once do not share it.
std::string uniqueName(const std::string& what) { return "shared-fixture-test-" + what + "-" + std::to_string(::getpid()); }

void removeShared(const std::string& name) {
    std::error_code ec;
    fs::remove_all(outputDir() / "shared" / name, ec);
    fs::remove(outputDir() / "shared" / (name + ".lock"), ec);
}

} // namespace

TEST(SharedFixtureTest, MadeOnceThenFoundMade) {
    const std::string name = uniqueName("once");
    int made = 0;
    auto make = [&](const fs::path& d) {
        ++made;
        std::ofstream(d / "a.txt") << "made";
        return true;
    };
    const auto first = sharedFixture(name, make);
    ASSERT_TRUE(first);
    EXPECT_EQ(readBytes(*first / "a.txt"), "made");
    const auto second = sharedFixture(name, make);
    ASSERT_TRUE(second);
    EXPECT_EQ(*second, *first);
    EXPECT_EQ(made, 1);
    removeShared(name);
}

TEST(SharedFixtureTest, FailedOrInterruptedMakeIsMadeAgain) {
    const std::string name = uniqueName("again");
    int made = 0;
    // A make that fails: nothing is left, and the next call makes it again.
    EXPECT_FALSE(sharedFixture(name, [&](const fs::path& d) {
        ++made;
        std::ofstream(d / "half.txt") << "half";
        return false;
    }));
    EXPECT_FALSE(fs::exists(outputDir() / "shared" / name));
    // A make killed part way (its files there, no stamp): made again from an empty folder.
    fs::create_directories(outputDir() / "shared" / name);
    std::ofstream(outputDir() / "shared" / name / "half.txt") << "half";
    const auto dir = sharedFixture(name, [&](const fs::path& d) {
        ++made;
        EXPECT_FALSE(fs::exists(d / "half.txt")) << "a part-made fixture was kept";
        std::ofstream(d / "whole.txt") << "whole";
        return true;
    });
    ASSERT_TRUE(dir);
    EXPECT_TRUE(fs::exists(*dir / "whole.txt"));
    EXPECT_EQ(made, 2);
    removeShared(name);
}

TEST(SharedFixtureTest, ProcessesAskingAtOnceShareOneMake) {
    const std::string name = uniqueName("concurrent");
    const fs::path counter = outputDir() / (name + ".makes");
    fs::remove(counter);
    // Four processes ask at once; each make appends a line and takes a moment, so a second make would show.
    std::vector<pid_t> children;
    for (int i = 0; i < 4; ++i) {
        const pid_t pid = ::fork();
        if (pid == 0) {
            const auto dir = sharedFixture(name, [&](const fs::path& d) {
                std::ofstream(counter, std::ios::app) << "make\n";
                ::usleep(200 * 1000);
                std::ofstream(d / "a.txt") << "made";
                return true;
            });
            ::_exit(dir && readBytes(*dir / "a.txt") == "made" ? 0 : 1);
        }
        children.push_back(pid);
    }
    for (const pid_t pid : children) {
        int status = 0;
        ::waitpid(pid, &status, 0);
        EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "a process did not find the fixture made";
    }
    EXPECT_EQ(readBytes(counter), "make\n");
    fs::remove(counter);
    removeShared(name);
}
