#pragma once
// A parallel loop over indices for core's codecs (tiles compressed by GeoTiffStreamWriter, tiles and strips
// decompressed by BandReader): each index is claimed by the next free thread, and `worker` tells the callback which
// thread it runs on, for per-thread scratch. Internal to core.
#include <algorithm>
#include <atomic>
#include <thread>
#include <vector>

namespace seasonview {

/// Calls fn(index, worker) for every index in [0, count) on up to `threads` threads (the calling thread is worker
/// 0; threads <= 1 runs inline); worker < threads. Returns when all are done.
template <class Fn> void parallelIndices(int count, int threads, const Fn& fn) {
    const int n = std::clamp(threads, 1, std::max(count, 1));
    if (n == 1) {
        for (int i = 0; i < count; ++i) fn(i, 0);
        return;
    }
    std::atomic<int> next{0};
    auto worker = [&](int w) {
        for (int i = next.fetch_add(1); i < count; i = next.fetch_add(1)) fn(i, w);
    };
    std::vector<std::thread> pool;
    pool.reserve(size_t(n - 1));
    for (int w = 1; w < n; ++w) pool.emplace_back(worker, w);
    worker(0);
    for (auto& t : pool) t.join();
}

} // namespace seasonview
