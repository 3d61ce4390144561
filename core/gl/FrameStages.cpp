#include "gl/FrameStages.h"

#include <epoxy/gl.h>

#include <chrono>

namespace seasonview::gl {
namespace {

using Clock = std::chrono::steady_clock;

struct Record {
    bool on = false, finish = true;
    Clock::time_point last;
    std::vector<StageTime> stages;
};
thread_local Record t_record;

double ms(Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

} // namespace

void beginFrameStages(bool finish) {
    t_record.on = true;
    t_record.finish = finish;
    t_record.stages.clear();
    t_record.last = Clock::now();
}

std::vector<StageTime> endFrameStages() {
    t_record.on = false;
    return std::move(t_record.stages);
}

void markStage(const char* name) {
    if (!t_record.on) return;
    const auto t0 = Clock::now();
    Clock::time_point t1 = t0;
    if (t_record.finish) {
        glFinish();
        t1 = Clock::now();
    }
    t_record.stages.push_back({name, ms(t0 - t_record.last), ms(t1 - t0)});
    t_record.last = t1;
}

} // namespace seasonview::gl
