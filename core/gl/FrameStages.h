#pragma once
// Where a frame's time goes, stage by stage (`bench --stages finish|issue`): renderers mark the end of each stage
// they issue (the streaming, the canopy's derivation, the terrain, the canopy's passes, the city's paging and
// draws); while a frame is profiled each mark records the CPU time since the previous mark (issuing the stage's
// commands, with whatever the driver does on the calling thread, waits for the GPU included), then
// - finish: waits for the GPU (glFinish) and records that wait (the stage's GPU work not overlapped with its
//   issuing). The waits serialise CPU and GPU, so such a frame is slower than a plain one: the figures say which
//   stage costs what, not the frame time;
// - issue: records no wait, so the frame runs as a plain one, and a stage whose CPU time holds a wait for the GPU
//   (an implicit synchronisation in the driver) shows it.
// When no frame is profiled a mark costs one branch. One GL context per thread, so the record is per thread.
#include <string>
#include <vector>

namespace seasonview::gl {

struct StageTime {
    std::string name;
    double cpuMs = 0;  // from the previous mark (or the frame's start) to this one
    double waitMs = 0; // glFinish at this mark
};

/// Starts profiling this thread's frame: marks from now on record, until endFrameStages(); `finish`: each mark
/// waits for the GPU.
void beginFrameStages(bool finish);
/// The frame's stages in order (a stage marked twice appears twice), and stops recording.
std::vector<StageTime> endFrameStages();
/// Marks the end of stage `name` (a string literal or one that outlives the frame) when a frame is profiled.
void markStage(const char* name);

} // namespace seasonview::gl
