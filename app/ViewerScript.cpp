#include "ViewerScript.h"
#include "JsonFile.h"

#include <algorithm>
#include <cmath>
#include <fstream>

namespace seasonview::app {

namespace {

Result<glm::dvec2> point(const nlohmann::json& j, const std::string& where) {
    if (!j.is_array() || j.size() != 2 || !j[0].is_number() || !j[1].is_number())
        return Error{where + ": expected [x, y] in window pixels"};
    return glm::dvec2(j[0].get<double>(), j[1].get<double>());
}

} // namespace

Result<std::vector<ScriptEvent>> parseViewerScript(const nlohmann::json& j, const std::string& source) {
    if (!j.is_array()) return Error{source + ": a viewer script is a JSON array of events"};
    std::vector<ScriptEvent> events;
    for (size_t i = 0; i < j.size(); ++i) {
        const nlohmann::json& e = j[i];
        const std::string where = source + ": event " + std::to_string(i);
        if (!e.is_object() || !e.contains("t") || !e["t"].is_number() || e["t"].get<double>() < 0.0)
            return Error{where + ": needs a time \"t\" in seconds (>= 0)"};
        ScriptEvent ev;
        ev.t = e["t"].get<double>();
        if (e.contains("duration")) {
            if (!e["duration"].is_number() || e["duration"].get<double>() < 0.0)
                return Error{where + ": \"duration\" must be a number of seconds >= 0"};
            ev.duration = e["duration"].get<double>();
        }
        if (e.contains("key")) {
            if (!e["key"].is_string() || e["key"].get<std::string>().empty())
                return Error{where + ": \"key\" must be a key name"};
            ev.kind = ScriptEvent::Kind::Key;
            ev.key = e["key"].get<std::string>();
        } else if (e.contains("hold")) {
            if (!e["hold"].is_string() || e["hold"].get<std::string>().empty())
                return Error{where + ": \"hold\" must be a key name"};
            ev.kind = ScriptEvent::Kind::Hold;
            ev.key = e["hold"].get<std::string>();
        } else if (e.contains("drag")) {
            const nlohmann::json& d = e["drag"];
            if (!d.is_array() || d.size() != 2) return Error{where + ": \"drag\" must be [[x0, y0], [x1, y1]]"};
            auto a = point(d[0], where + " drag start");
            if (!a) return a.error();
            auto b = point(d[1], where + " drag end");
            if (!b) return b.error();
            ev.kind = ScriptEvent::Kind::Drag;
            ev.from = *a;
            ev.to = *b;
            const std::string button = e.value("button", std::string("left"));
            if (button != "left" && button != "right") return Error{where + ": \"button\" must be left or right"};
            ev.button = button == "left" ? 0 : 1;
        } else if (e.contains("wheel")) {
            if (!e["wheel"].is_number()) return Error{where + ": \"wheel\" must be a number of notches"};
            ev.kind = ScriptEvent::Kind::Wheel;
            ev.wheel = e["wheel"].get<double>();
            if (e.contains("at")) {
                auto p = point(e["at"], where + " at");
                if (!p) return p.error();
                ev.to = *p;
                ev.from = *p;
                ev.button = 1; // marks "cursor given"
            } else
                ev.button = 0;
        } else if (e.contains("move")) {
            auto p = point(e["move"], where + " move");
            if (!p) return p.error();
            ev.kind = ScriptEvent::Kind::Move;
            ev.to = *p;
        } else if (e.contains("set")) {
            if (!e["set"].is_string() || !e.contains("value"))
                return Error{where + ": \"set\" needs a setting name and a \"value\""};
            ev.kind = ScriptEvent::Kind::Set;
            ev.key = e["set"].get<std::string>();
            ev.value = e["value"];
        } else
            return Error{where + ": expected one of key, hold, drag, wheel, move, set"};
        events.push_back(std::move(ev));
    }
    std::stable_sort(events.begin(), events.end(), [](const ScriptEvent& a, const ScriptEvent& b) { return a.t < b.t; });
    return events;
}

Result<std::vector<ScriptEvent>> loadViewerScript(const std::filesystem::path& file) {
    auto j = readJsonFile(file, "viewer script");
    if (!j) return j.error();
    return parseViewerScript(*j, file.string());
}

ScriptFrame scriptFrame(const std::vector<ScriptEvent>& events, double t0, double t1) {
    ScriptFrame f;
    // The event starts in (t0, t1]; the first frame (t0 < 0) also takes events at time 0.
    auto startsIn = [&](double t) { return t > t0 && t <= t1; };
    for (const ScriptEvent& e : events) {
        switch (e.kind) {
        case ScriptEvent::Kind::Key:
            if (startsIn(e.t)) f.pressed.push_back(e.key);
            break;
        case ScriptEvent::Kind::Hold:
            // Down over [t, t + duration): the frame holds it for the part of (t0, t1] inside.
            if (e.t < t1 && e.t + e.duration > t0) f.held.push_back(e.key);
            break;
        case ScriptEvent::Kind::Drag: {
            const double end = e.t + e.duration;
            if (t1 < e.t || t0 >= end) break;
            auto at = [&](double t) {
                if (e.duration <= 0.0) return t >= e.t ? e.to : e.from;
                const double u = std::clamp((t - e.t) / e.duration, 0.0, 1.0);
                return e.from + (e.to - e.from) * u;
            };
            if (startsIn(e.t) || (t0 < e.t && e.t <= t1)) {
                f.dragStarted = true;
                f.dragStart = e.from;
            }
            const glm::dvec2 a = at(std::max(t0, e.t)), b = at(t1);
            f.drag += b - a;
            f.dragButton = e.button;
            f.cursorSet = true;
            f.cursor = b;
            break;
        }
        case ScriptEvent::Kind::Wheel:
            if (startsIn(e.t)) {
                f.wheel += e.wheel;
                if (e.button == 1) {
                    f.cursorSet = true;
                    f.cursor = e.to;
                }
            }
            break;
        case ScriptEvent::Kind::Move:
            if (startsIn(e.t)) {
                f.cursorSet = true;
                f.cursor = e.to;
            }
            break;
        case ScriptEvent::Kind::Set:
            if (startsIn(e.t)) f.settings.emplace_back(e.key, e.value);
            break;
        }
    }
    return f;
}

double scriptEnd(const std::vector<ScriptEvent>& events) {
    double end = 0.0;
    for (const ScriptEvent& e : events) end = std::max(end, e.t + e.duration);
    return end;
}

Result<TimedScreenshot> parseTimedScreenshot(const std::string& text) {
    const size_t colon = text.find(':');
    if (colon == std::string::npos || colon == 0 || colon + 1 >= text.size())
        return Error{"--screenshot-at '" + text + "': expected T:FILE (seconds, then a .png path)"};
    TimedScreenshot s;
    try {
        size_t used = 0;
        s.t = std::stod(text.substr(0, colon), &used);
        if (used != colon || !std::isfinite(s.t) || s.t < 0.0) throw std::invalid_argument("t");
    } catch (const std::exception&) {
        return Error{"--screenshot-at '" + text + "': the time before ':' must be seconds >= 0"};
    }
    s.file = text.substr(colon + 1);
    return s;
}

} // namespace seasonview::app
