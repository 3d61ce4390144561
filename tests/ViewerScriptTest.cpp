// The viewer's script timeline (app/ViewerScript.h), plain C++: events land in the frame that covers their time,
// a drag split over frames adds up to the whole motion, held keys cover their interval, bad scripts are rejected
// with the event named.
#include "ViewerScript.h"

#include <gtest/gtest.h>

using namespace seasonview;
using namespace seasonview::app;

namespace {
std::vector<ScriptEvent> parse(const char* text) {
    auto r = parseViewerScript(nlohmann::json::parse(text), "s.json");
    EXPECT_TRUE(r.ok()) << r.message();
    return r ? *r : std::vector<ScriptEvent>{};
}
} // namespace

TEST(ViewerScriptTest, EventsLandInTheFrameCoveringTheirTime) {
    const auto ev = parse(R"([{"t": 0, "key": "2"}, {"t": 0.5, "key": "C"}, {"t": 0.4, "wheel": 2, "at": [10, 20]},
                              {"t": 0.7, "set": "blend", "value": 0.25}])");
    ASSERT_EQ(ev.size(), 4u);
    EXPECT_EQ(ev[1].kind, ScriptEvent::Kind::Wheel) << "sorted by time";
    const double dt = 0.1;
    int keys = 0, wheels = 0, sets = 0;
    for (int f = 0; f < 10; ++f) {
        const double t1 = f * dt, t0 = f == 0 ? -1.0 : t1 - dt;
        const ScriptFrame s = scriptFrame(ev, t0, t1);
        keys += int(s.pressed.size());
        if (f == 0) {
            EXPECT_EQ(s.pressed, std::vector<std::string>{"2"});
        }
        if (s.wheel != 0.0) {
            ++wheels;
            EXPECT_EQ(f, 4);
            EXPECT_DOUBLE_EQ(s.wheel, 2.0);
            EXPECT_EQ(s.cursor, glm::dvec2(10, 20));
        }
        for (const auto& [name, value] : s.settings) {
            ++sets;
            EXPECT_EQ(name, "blend");
            EXPECT_DOUBLE_EQ(value.get<double>(), 0.25);
        }
    }
    EXPECT_EQ(keys, 2);
    EXPECT_EQ(wheels, 1);
    EXPECT_EQ(sets, 1);
}

TEST(ViewerScriptTest, DragSplitOverFramesAddsUpAndHoldsCoverTheirInterval) {
    const auto ev = parse(R"([{"t": 0.25, "drag": [[100, 50], [40, 110]], "duration": 0.5},
                              {"t": 1.0, "hold": "W", "duration": 0.25}])");
    glm::dvec2 total(0.0);
    int started = 0, held = 0;
    for (int f = 0; f < 60; ++f) {
        const double t1 = f / 30.0, t0 = f == 0 ? -1.0 : (f - 1) / 30.0;
        const ScriptFrame s = scriptFrame(ev, t0, t1);
        total += s.drag;
        if (s.dragStarted) {
            ++started;
            EXPECT_EQ(s.dragStart, glm::dvec2(100, 50));
        }
        if (s.dragButton == 0) {
            EXPECT_GE(t1, 0.25);
            EXPECT_LE(t0, 0.75);
        }
        if (!s.held.empty()) {
            ++held;
            EXPECT_EQ(s.held, std::vector<std::string>{"W"});
            EXPECT_GT(t1, 1.0);
            EXPECT_LT(t0, 1.25);
        }
    }
    EXPECT_NEAR(total.x, -60.0, 1e-9);
    EXPECT_NEAR(total.y, 60.0, 1e-9);
    EXPECT_EQ(started, 1);
    EXPECT_EQ(held, 8); // frames 31..38 of 1/30 s overlap [1.0, 1.25)
    EXPECT_NEAR(scriptEnd(ev), 1.25, 1e-12);
}

TEST(ViewerScriptTest, BadScriptsNameTheEvent) {
    for (auto [text, message] : {std::pair{R"({"t": 1})", "a JSON array"},
                                 std::pair{R"([{"key": "A"}])", "event 0: needs a time"},
                                 std::pair{R"([{"t": 1, "key": "A"}, {"t": 2, "drag": [[1, 2]]}])", "event 1"},
                                 std::pair{R"([{"t": 1, "fly": true}])", "expected one of"},
                                 std::pair{R"([{"t": 1, "drag": [[0, 0], [1, 1]], "button": "middle"}])", "left or right"},
                                 std::pair{R"([{"t": 1, "hold": "W", "duration": -1}])", "duration"}}) {
        auto r = parseViewerScript(nlohmann::json::parse(text), "s.json");
        ASSERT_FALSE(r.ok()) << text;
        EXPECT_NE(r.message().find(message), std::string::npos) << r.message();
        EXPECT_EQ(r.message().rfind("s.json", 0), 0u) << "names the file";
    }
    auto missing = loadViewerScript("/nonexistent/s.json");
    ASSERT_FALSE(missing.ok());
    EXPECT_NE(missing.message().find("file not found"), std::string::npos);
    EXPECT_TRUE(parseTimedScreenshot("2.5:a.png").ok());
    EXPECT_DOUBLE_EQ(parseTimedScreenshot("2.5:a.png")->t, 2.5);
    EXPECT_FALSE(parseTimedScreenshot("a.png").ok());
    EXPECT_FALSE(parseTimedScreenshot("-1:a.png").ok());
    EXPECT_FALSE(parseTimedScreenshot("1.5x:a.png").ok());
}
