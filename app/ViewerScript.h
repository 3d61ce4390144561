#pragma once
// Timed input for `seasonview view --script FILE`, so the viewer runs without a person (tests, demos, recordings).
// The file is a JSON array of events, each with a start time "t" in seconds of the viewer's clock:
//   {"t": 0.5, "key": "2"}                                  press and release a key (names as in the viewer's help)
//   {"t": 1.0, "hold": "W", "duration": 2.0}                hold a key down
//   {"t": 1.0, "drag": [[x0, y0], [x1, y1]], "duration": 0.5 [, "button": "left" | "right"]}
//                                                           drag with a mouse button, window pixels, top-left origin
//   {"t": 2.0, "wheel": 2 [, "at": [x, y]]}                 wheel notches (positive: zoom in) at a cursor position
//   {"t": 2.5, "move": [x, y]}                              move the cursor
//   {"t": 3.0, "set": "blend", "value": 0.3}                a panel setting (see ViewerSettings::set)
// Events drive the same handlers as the window's own input.
#include "Result.h"

#include <glm/vec2.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace seasonview::app {

struct ScriptEvent {
    enum class Kind { Key, Hold, Drag, Wheel, Move, Set };
    Kind kind = Kind::Key;
    double t = 0.0;
    double duration = 0.0;
    std::string key;                 // Key, Hold: key name; Set: setting name
    glm::dvec2 from{0.0}, to{0.0};   // Drag: start and end; Wheel, Move: `to` is the cursor
    int button = 0;                  // Drag: 0 left, 1 right
    double wheel = 0.0;
    nlohmann::json value;            // Set
};

/// Parses a script; errors name the file and the event (index, what is wrong).
Result<std::vector<ScriptEvent>> loadViewerScript(const std::filesystem::path& file);
Result<std::vector<ScriptEvent>> parseViewerScript(const nlohmann::json& j, const std::string& source);

/// What a script does in the frame covering (t0, t1]: keys pressed, keys held, cursor motion, buttons, wheel,
/// settings. Drags move the cursor linearly over their duration: the frame gets the part of the motion in (t0, t1].
struct ScriptFrame {
    std::vector<std::string> pressed;   // keys pressed (and released) in this frame
    std::vector<std::string> held;      // keys down during this frame
    bool cursorSet = false;
    glm::dvec2 cursor{0.0};             // where the cursor is at t1
    glm::dvec2 drag{0.0};               // motion with a button held during the frame
    int dragButton = -1;                // -1: none
    bool dragStarted = false;           // a drag began in this frame (at `dragStart`)
    glm::dvec2 dragStart{0.0};
    double wheel = 0.0;
    std::vector<std::pair<std::string, nlohmann::json>> settings;
};
ScriptFrame scriptFrame(const std::vector<ScriptEvent>& events, double t0, double t1);

/// The time after which the script does nothing more.
double scriptEnd(const std::vector<ScriptEvent>& events);

/// A `--screenshot-at T:FILE` argument.
struct TimedScreenshot {
    double t = 0.0;
    std::filesystem::path file;
};
Result<TimedScreenshot> parseTimedScreenshot(const std::string& text);

} // namespace seasonview::app
